//! URDF loading: host-sim loads any serial chain of revolute joints.
//!
//! The reference is the raw URDF tree, every link included (fixed ones too), walked with
//! nalgebra isometries: mass, CoM, H~b and H~bm (by central differences of link velocities)
//! must match the core running on the extracted chain, which proves the composition of
//! fixed joints and the merging of rigid attachments.
//!
//! Requirements: RL-SIM-URDF, RL-SIM-TASK, RL-ROB, and through host-sim RL-MODEL, RL-MOM
//! (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use host_sim::urdf::{Chain, parse};
use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3};
use reactionless::{CHASER7, Frames, Momentum, Robot};
use std::collections::BTreeMap;

fn read(name: &str) -> String {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    std::fs::read_to_string(format!("{root}/{name}")).unwrap()
}

/// spec/chaser7.urdf loads to the bits of CHASER7, the end effector named or found as the
/// only leaf.
/// Verifies RL-MODEL-003, RL-SIM-TASK-003, RL-SIM-URDF-002.
#[test]
fn chaser7_urdf_loads_to_the_bits_of_the_const() {
    let chain = parse(&read("spec/chaser7.urdf"), Some("ee")).unwrap();
    assert_eq!(chain.desc::<7>().unwrap(), CHASER7);
    // Also with the end effector found as the only leaf.
    let chain = parse(&read("spec/chaser7.urdf"), None).unwrap();
    assert_eq!(chain.desc::<7>().unwrap(), CHASER7);
    assert_eq!(chain.ee_link, "ee");
}

fn iso(p: &urdf_rs::Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.xyz[0], p.xyz[1], p.xyz[2]),
        UnitQuaternion::from_euler_angles(p.rpy[0], p.rpy[1], p.rpy[2]),
    )
}

/// World pose of every link of the URDF tree for joint values by name.
fn tree_fk(robot: &urdf_rs::Robot, q: &BTreeMap<String, f64>) -> BTreeMap<String, Isometry3<f64>> {
    let mut poses = BTreeMap::new();
    let children: Vec<&str> = robot.joints.iter().map(|j| j.child.link.as_str()).collect();
    let root = robot
        .links
        .iter()
        .find(|l| !children.contains(&l.name.as_str()))
        .unwrap();
    poses.insert(root.name.clone(), Isometry3::identity());
    for _ in 0..robot.joints.len() {
        for j in &robot.joints {
            if let Some(parent) = poses.get(&j.parent.link).copied() {
                let angle = q.get(&j.name).copied().unwrap_or(0.0);
                let axis =
                    Unit::new_normalize(Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]));
                let motion = Isometry3::from_parts(
                    Translation3::identity(),
                    UnitQuaternion::from_axis_angle(&axis, angle),
                );
                poses.insert(j.child.link.clone(), parent * iso(&j.origin) * motion);
            }
        }
    }
    poses
}

struct Body {
    m: f64,
    c: Vector3<f64>,
    i: Matrix3<f64>,
    r: Matrix3<f64>,
}

fn bodies(robot: &urdf_rs::Robot, q: &BTreeMap<String, f64>) -> Vec<Body> {
    let poses = tree_fk(robot, q);
    robot
        .links
        .iter()
        .filter(|l| l.inertial.mass.value > 0.0)
        .map(|l| {
            let frame = poses[&l.name] * iso(&l.inertial.origin);
            let r = *frame.rotation.to_rotation_matrix().matrix();
            let t = &l.inertial.inertia;
            let local = Matrix3::new(
                t.ixx, t.ixy, t.ixz, t.ixy, t.iyy, t.iyz, t.ixz, t.iyz, t.izz,
            );
            Body {
                m: l.inertial.mass.value,
                c: frame.translation.vector,
                i: r * local * r.transpose(),
                r,
            }
        })
        .collect()
}

fn com(b: &[Body]) -> Vector3<f64> {
    b.iter().map(|x| x.c * x.m).sum::<Vector3<f64>>() / b.iter().map(|x| x.m).sum::<f64>()
}

/// Compares the core on the extracted chain with the raw tree at configuration `q`.
fn compare<const N: usize>(robot: &urdf_rs::Robot, chain: &Chain, q: &[f64; N]) -> f64 {
    let core = Robot::new(&chain.desc::<N>().unwrap()).unwrap();
    let frames = Frames::new(&core, q);
    let m = Momentum::new(&core, &frames);
    let names: BTreeMap<String, f64> = chain
        .joint_names
        .iter()
        .cloned()
        .zip(q.iter().copied())
        .collect();
    let b = bodies(robot, &names);
    let total: f64 = b.iter().map(|x| x.m).sum();
    assert!((total - core.total_mass()).abs() < 1e-9 * total, "mass");
    let rg = com(&b);
    assert!(
        (rg - frames.com).norm() < 1e-12,
        "CoM {rg} vs {}",
        frames.com
    );
    let mut hb = Matrix3::zeros();
    for x in &b {
        let d = x.c - rg;
        hb += x.i + x.m * (d.norm_squared() * Matrix3::identity() - d * d.transpose());
    }
    let mut worst = (hb - m.hb.to_matrix()).norm() / hb.norm();
    let h = 1e-6;
    let scale = m.hbm.iter().map(|c| c.norm()).fold(0.0, f64::max);
    for (j, name) in chain.joint_names.iter().enumerate() {
        let mut plus = names.clone();
        let mut minus = names.clone();
        *plus.get_mut(name).unwrap() += h;
        *minus.get_mut(name).unwrap() -= h;
        let (bp, bm) = (bodies(robot, &plus), bodies(robot, &minus));
        let mut l = Vector3::zeros();
        for ((x, p), n) in b.iter().zip(&bp).zip(&bm) {
            let v = (p.c - n.c) / (2.0 * h);
            let dr = p.r * n.r.transpose();
            let w = Vector3::new(
                dr[(2, 1)] - dr[(1, 2)],
                dr[(0, 2)] - dr[(2, 0)],
                dr[(1, 0)] - dr[(0, 1)],
            ) / (4.0 * h);
            l += x.i * w + x.m * (x.c - rg).cross(&v);
        }
        worst = worst.max((l - m.hbm[j]).norm() / scale);
    }
    // End effector.
    let ee = tree_fk(robot, &names)[&chain.ee_link];
    assert!(
        (ee.translation.vector - frames.ee_position).norm() < 1e-12,
        "ee position"
    );
    let r = UnitQuaternion::from_matrix(&frames.ee_rotation);
    assert!(r.angle_to(&ee.rotation) < 1e-12, "ee attitude");
    worst
}

/// Fixed joints and attachments composed and merged: mass, CoM, H~b, H~bm, end pose match
/// the raw URDF tree.
/// Verifies RL-MODEL-002, RL-MOM-001, RL-SIM-URDF-001.
#[test]
fn fixed_joints_and_attachments_are_composed_and_merged_exactly() {
    for (file, n) in [
        ("tests/robots/arm6.urdf", 6),
        ("tests/robots/arm9.urdf", 9),
        ("spec/chaser7.urdf", 7),
    ] {
        let text = read(file);
        let robot = urdf_rs::read_from_string(&text).unwrap();
        let chain = parse(&text, Some("ee")).unwrap();
        assert_eq!(chain.dof(), n);
        let mut worst: f64 = 0.0;
        for k in 0..20 {
            let q: Vec<f64> = (0..n)
                .map(|i| ((i * 7 + k * 13) % 17) as f64 / 17.0 * 3.0 - 1.5)
                .collect();
            worst = worst.max(match n {
                6 => compare::<6>(&robot, &chain, &q.clone().try_into().unwrap()),
                7 => compare::<7>(&robot, &chain, &q.clone().try_into().unwrap()),
                _ => compare::<9>(&robot, &chain, &q.clone().try_into().unwrap()),
            });
        }
        assert!(worst < 1e-6, "{file}: worst relative error {worst:e}");
    }
}

fn chaser_with(edit: impl Fn(String) -> String) -> String {
    edit(read("spec/chaser7.urdf"))
}

fn err(text: &str, ee: Option<&str>) -> String {
    parse(text, ee).unwrap_err()
}

/// Each unsupported URDF (not XML, non-revolute, branching, several roots, massless, …) is
/// named by link or joint.
/// Verifies RL-ROB-011.
#[test]
fn unsupported_urdf_is_named() {
    let e = err("this is not xml", None);
    assert!(e.contains("not a readable URDF"), "{e}");
    let e = err(
        &chaser_with(|s| {
            s.replace(
                r#"name="j3" type="revolute""#,
                r#"name="j3" type="prismatic""#,
            )
        }),
        None,
    );
    assert!(e.contains("joint 'j3'") && e.contains("Prismatic"), "{e}");
    let e = err(
        &chaser_with(|s| {
            s.replace(
                r#"name="j5" type="revolute""#,
                r#"name="j5" type="continuous""#,
            )
        }),
        None,
    );
    assert!(e.contains("joint 'j5'") && e.contains("Continuous"), "{e}");
    let e = err(&read("spec/chaser7.urdf"), Some("nope"));
    assert!(e.contains("'nope'"), "{e}");
    // Branching: a revolute joint off the chain.
    let branch = chaser_with(|s| {
        s.replace(
            "</robot>",
            r#"<joint name="side" type="revolute"><parent link="link2"/><child link="extra"/><origin xyz="0 0 0"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" velocity="1"/></joint><link name="extra"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link></robot>"#,
        )
    });
    let e = err(&branch, Some("ee"));
    assert!(e.contains("branching") && e.contains("'side'"), "{e}");
    // Joints beyond the chosen end effector.
    let e = err(&read("spec/chaser7.urdf"), Some("link3"));
    assert!(
        e.contains("'j4'") && e.contains("beyond the end-effector link 'link3'"),
        "{e}"
    );
    // Three joints: chaser7 cut after link3.
    let full = read("spec/chaser7.urdf");
    let cut = format!(
        "{}</robot>",
        &full[..full.find(r#"<joint name="j4""#).unwrap()]
    );
    let e = err(&cut, None);
    assert!(
        e.contains("3 revolute joints") && e.contains("4..=12"),
        "{e}"
    );
    // Negative mass.
    let e = err(
        &chaser_with(|s| s.replace(r#"<mass value="25"/>"#, r#"<mass value="-25"/>"#)),
        None,
    );
    assert!(
        e.contains("link 'link2'") && e.contains("negative mass"),
        "{e}"
    );
    // A moving body without mass.
    let e = err(
        &chaser_with(|s| s.replace(r#"<mass value="5"/>"#, r#"<mass value="0"/>"#)),
        None,
    );
    assert!(e.contains("'link3'") && e.contains("no mass"), "{e}");
    // Two roots.
    let e = err(
        &chaser_with(|s| s.replace("</robot>", r#"<link name="floating"/></robot>"#)),
        Some("ee"),
    );
    assert!(e.contains("several root links"), "{e}");
}

/// The core's robot validation errors are reported with the URDF's link and joint names.
/// Verifies RL-ROB-001, RL-ROB-011.
#[test]
fn core_validation_errors_are_explained_with_urdf_names() {
    let text = chaser_with(|s| s.replace(r#"<axis xyz="0 0 1"/>"#, r#"<axis xyz="0 0 0"/>"#));
    let chain = parse(&text, None).unwrap();
    let e = Robot::new(&chain.desc::<7>().unwrap()).unwrap_err();
    assert!(
        chain.explain(&e).contains("joint 'j2'"),
        "{}",
        chain.explain(&e)
    );
    let text = chaser_with(|s| s.replace(r#"ixx="0.056""#, r#"ixx="-0.056""#));
    let chain = parse(&text, None).unwrap();
    let e = Robot::new(&chain.desc::<7>().unwrap()).unwrap_err();
    assert_eq!(
        chain.explain(&e),
        "inertia of link 'link2' is not positive definite"
    );
}
