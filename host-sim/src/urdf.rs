//! URDF → the core's plain robot description.
//!
//! Owns the chain extraction: the path of joints from the root link to the end-effector
//! link must consist of revolute and fixed joints only. Fixed joints on the path are
//! composed into the next revolute joint's origin (or into the end-effector frame); links
//! hanging off the path through fixed joints only are rigid attachments whose mass is merged
//! into the body they are fixed to. Anything else (other joint types, movable joints off the
//! path, several roots) is rejected with a message that names the element.
//!
//! Where nothing needs composing or merging, values are passed through untouched, so a URDF
//! written like `spec/chaser7.urdf` loads to exactly the bits of [`reactionless::CHASER7`].
//!
//! Collision geometry (spec §13): every `<collision>` of a body's links, placed in the
//! body's frame ([`Collider`]). Spheres, boxes and `<capsule>`s are read as they are; a
//! `<cylinder>` whose `<collision name>` contains `capsule` is the capsule of that radius
//! and segment length (the convention of Pinocchio users, whose URDF parser has no
//! capsule); any other cylinder and every mesh are refused, naming the link.

use crate::error::{CliError, Context};
use reactionless::collision::Shape;
use reactionless::geometry::{Mat3, Sym3, Vec3, matrix_rpy, rpy_matrix};
use reactionless::{BodyDesc, Inertia, JointDesc, Origin, Robot};
use std::collections::BTreeMap;
use std::path::Path;

/// Joint counts host-sim can instantiate the core for.
pub const MIN_JOINTS: usize = 4;
/// Largest supported joint count.
pub const MAX_JOINTS: usize = 12;

/// A serial chain read from URDF, with names for messages and reports.
#[derive(Debug, Clone)]
pub struct Chain {
    /// Robot name from the URDF.
    pub name: String,
    /// Root link name.
    pub base_link: String,
    /// Revolute joint names, base to tip.
    pub joint_names: Vec<String>,
    /// Link moved by each revolute joint.
    pub link_names: Vec<String>,
    /// End-effector link name.
    pub ee_link: String,
    /// Base body.
    pub base: BodyDesc,
    /// Revolute joints, base to tip.
    pub joints: Vec<JointDesc>,
    /// Bodies moved by each joint (with their fixed attachments merged).
    pub links: Vec<BodyDesc>,
    /// End-effector frame in the last body's frame.
    pub end_effector: Origin,
    /// Collision primitives of each body: the base, then links `1..=N`.
    pub collision: Vec<Vec<Collider>>,
}

/// A collision primitive of a body, in the body's frame (spec §13).
#[derive(Debug, Clone, PartialEq)]
pub struct Collider {
    /// For reports: the `<collision name>`, else `<link>/<k>` (`k`-th of that URDF link).
    pub name: String,
    /// The primitive (m).
    pub shape: Shape,
    /// The primitive's frame in the body's frame.
    pub origin: Origin,
}

impl Chain {
    /// Number of collision primitives on the robot (base and links).
    pub fn collider_count(&self) -> usize {
        self.collision.iter().map(Vec::len).sum()
    }

    /// Number of revolute joints `N`.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The core description for `N` joints (the caller dispatched on [`Chain::dof`]).
    pub fn desc<const N: usize>(&self) -> Result<reactionless::RobotDesc<N>, CliError> {
        let joints: [JointDesc; N] = self
            .joints
            .clone()
            .try_into()
            .map_err(|_| CliError::internal("joint count mismatch"))?;
        let links: [BodyDesc; N] = self
            .links
            .clone()
            .try_into()
            .map_err(|_| CliError::internal("link count mismatch"))?;
        Ok(reactionless::RobotDesc {
            base: self.base,
            joints,
            links,
            end_effector: self.end_effector,
        })
    }

    /// The validated robot model for `N` joints; an error names `origin` (the URDF file)
    /// and the URDF's element names.
    pub fn robot<const N: usize>(&self, origin: &Path) -> Result<Robot<N>, CliError> {
        Robot::new(&self.desc::<N>()?)
            .map_err(|e| CliError::input(format!("{}: {}", origin.display(), self.explain(&e))))
    }

    /// Human name of a body for messages: `base link 'base'` or `link 'link3'`.
    pub fn body_name(&self, body: reactionless::Body) -> String {
        match body {
            reactionless::Body::Base => format!("base link '{}'", self.base_link),
            reactionless::Body::Link(i) => match self.link_names.get(usize::from(i) - 1) {
                Some(n) => format!("link '{n}'"),
                None => format!("link {i}"),
            },
        }
    }

    /// Human name of joint `j` (1-based).
    pub fn joint_name(&self, j: u8) -> String {
        match self.joint_names.get(usize::from(j).wrapping_sub(1)) {
            Some(n) => format!("joint '{n}'"),
            None => format!("joint {j}"),
        }
    }

    /// Rewrites a core model error with the URDF's names.
    pub fn explain(&self, e: &reactionless::Error) -> String {
        use reactionless::{Error as E, Param as P};
        match e {
            E::NotFinite(p) | E::NotPositive(p) => {
                let what = match p {
                    P::Mass(b) => format!("mass of {}", self.body_name(*b)),
                    P::CenterOfMass(b) => format!("inertial origin of {}", self.body_name(*b)),
                    P::Inertia(b) => format!("inertia of {}", self.body_name(*b)),
                    P::JointOrigin(j) => format!("origin of {}", self.joint_name(*j)),
                    P::JointAxis(j) => format!("axis of {}", self.joint_name(*j)),
                    P::LowerLimit(j) => format!("lower limit of {}", self.joint_name(*j)),
                    P::UpperLimit(j) => format!("upper limit of {}", self.joint_name(*j)),
                    P::VelocityLimit(j) => format!("velocity limit of {}", self.joint_name(*j)),
                    P::EndEffector => format!("frame of end-effector link '{}'", self.ee_link),
                    other => other.to_string(),
                };
                if matches!(e, E::NotFinite(_)) {
                    format!("{what} is not a finite number")
                } else {
                    format!("{what} must be strictly positive")
                }
            }
            E::InertiaNotPositiveDefinite(b) => {
                format!("inertia of {} is not positive definite", self.body_name(*b))
            }
            E::AxisNotUnit { joint, tolerance } => format!(
                "axis of {} is not a unit vector (|norm - 1| > {tolerance:e})",
                self.joint_name(*joint),
            ),
            E::LimitsInverted(j) => format!(
                "{}: lower limit is not below the upper limit",
                self.joint_name(*j)
            ),
            other => other.to_string(),
        }
    }
}

/// `chain` as a URDF document: one link per body (its merged inertial), the revolute
/// joints with their limits, and the end-effector link on a fixed joint. Every number is
/// written in its shortest round-trip form, so [`parse`] reads back the same bits.
pub fn write(chain: &Chain) -> String {
    let n = |v: f64| ryu::Buffer::new().format(v).to_string();
    let v3 = |v: [f64; 3]| format!("{} {} {}", n(v[0]), n(v[1]), n(v[2]));
    let esc = |s: &str| {
        s.replace('&', "&amp;")
            .replace('<', "&lt;")
            .replace('>', "&gt;")
            .replace('"', "&quot;")
    };
    let collisions = |cs: &[Collider]| {
        let mut out = String::new();
        for c in cs {
            let (name, geometry) = match c.shape {
                Shape::Sphere { radius } => (
                    c.name.clone(),
                    format!("<sphere radius=\"{}\"/>", n(radius)),
                ),
                Shape::Box { half } => (
                    c.name.clone(),
                    format!("<box size=\"{}\"/>", v3(half.map(|h| 2.0 * h))),
                ),
                Shape::Capsule { length, radius } => (
                    if c.name.to_ascii_lowercase().contains("capsule") {
                        c.name.clone()
                    } else {
                        format!("{}_capsule", c.name)
                    },
                    format!(
                        "<cylinder radius=\"{}\" length=\"{}\"/>",
                        n(radius),
                        n(length)
                    ),
                ),
            };
            out.push_str(&format!(
                "    <collision name=\"{}\"><origin xyz=\"{}\" rpy=\"{}\"/><geometry>{geometry}</geometry></collision>\n",
                esc(&name),
                v3(c.origin.xyz),
                v3(c.origin.rpy)
            ));
        }
        out
    };
    let none: Vec<Collider> = Vec::new();
    let body_collisions = |k: usize| collisions(chain.collision.get(k).unwrap_or(&none));
    let link = |name: &str, b: &BodyDesc, k: usize| {
        let i = &b.inertia;
        format!(
            "  <link name=\"{}\">\n    <inertial><origin xyz=\"{}\" rpy=\"{}\"/><mass value=\"{}\"/>\n      <inertia ixx=\"{}\" ixy=\"{}\" ixz=\"{}\" iyy=\"{}\" iyz=\"{}\" izz=\"{}\"/></inertial>\n{}  </link>\n",
            esc(name),
            v3(b.inertial.xyz),
            v3(b.inertial.rpy),
            n(b.mass),
            n(i.ixx),
            n(i.ixy),
            n(i.ixz),
            n(i.iyy),
            n(i.iyz),
            n(i.izz),
            body_collisions(k)
        )
    };
    let mut out = format!(
        "<?xml version=\"1.0\"?>\n<!-- written by host-sim {} -->\n<robot name=\"{}\">\n",
        env!("CARGO_PKG_VERSION"),
        esc(&chain.name)
    );
    out.push_str(&link(&chain.base_link, &chain.base, 0));
    let mut parent = chain.base_link.as_str();
    for (k, ((j, name), (l, lname))) in chain
        .joints
        .iter()
        .zip(&chain.joint_names)
        .zip(chain.links.iter().zip(&chain.link_names))
        .enumerate()
    {
        out.push_str(&format!(
            "  <joint name=\"{}\" type=\"revolute\">\n    <parent link=\"{}\"/><child link=\"{}\"/>\n    <origin xyz=\"{}\" rpy=\"{}\"/><axis xyz=\"{}\"/>\n    <limit lower=\"{}\" upper=\"{}\" velocity=\"{}\" effort=\"100\"/>\n  </joint>\n",
            esc(name),
            esc(parent),
            esc(lname),
            v3(j.origin.xyz),
            v3(j.origin.rpy),
            v3(j.axis),
            n(j.lower),
            n(j.upper),
            n(j.velocity)
        ));
        out.push_str(&link(lname, l, k + 1));
        parent = lname;
    }
    if chain.ee_link != parent {
        let e = &chain.end_effector;
        out.push_str(&format!(
            "  <joint name=\"{}_fixed\" type=\"fixed\">\n    <parent link=\"{}\"/><child link=\"{}\"/><origin xyz=\"{}\" rpy=\"{}\"/>\n  </joint>\n  <link name=\"{}\"/>\n",
            esc(&chain.ee_link),
            esc(parent),
            esc(&chain.ee_link),
            v3(e.xyz),
            v3(e.rpy),
            esc(&chain.ee_link)
        ));
    }
    out.push_str("</robot>\n");
    out
}

/// A rigid transform.
#[derive(Debug, Clone, Copy)]
struct Tf {
    r: Mat3,
    t: Vec3,
}

impl Tf {
    fn identity() -> Self {
        Self {
            r: Mat3::identity(),
            t: Vec3::zeros(),
        }
    }

    fn from_pose(p: &urdf_rs::Pose) -> Self {
        Self {
            r: rpy_matrix(p.rpy.0),
            t: Vec3::from(p.xyz.0),
        }
    }

    fn then(&self, o: &Tf) -> Tf {
        Tf {
            r: self.r * o.r,
            t: self.t + self.r * o.t,
        }
    }

    fn origin(&self) -> Origin {
        Origin {
            xyz: [self.t.x, self.t.y, self.t.z],
            rpy: matrix_rpy(&self.r),
        }
    }
}

fn pose_origin(p: &urdf_rs::Pose) -> Origin {
    Origin {
        xyz: p.xyz.0,
        rpy: p.rpy.0,
    }
}

/// One mass-carrying part of a body: a URDF link and its pose in the body frame.
struct Part<'a> {
    link: &'a urdf_rs::Link,
    /// Link frame in the body frame; `None` = the body's own link (identity).
    in_body: Option<Tf>,
}

/// Reads and extracts the chain from a URDF file.
pub fn load(path: &Path, ee: Option<&str>) -> Result<Chain, CliError> {
    let text = std::fs::read_to_string(path)
        .or_input(|| format!("{}: cannot read URDF", path.display()))?;
    parse(&text, ee).map_err(|m| CliError::input(format!("{}: {m}", path.display())))
}

/// Extracts the chain from URDF text. Errors are messages without the file name.
///
/// The steps: the link graph and its root ([`Graph::new`]); the end-effector link
/// ([`Graph::end_effector`]); the joint path from the root to it ([`Graph::path`]); the
/// fixed joints on the path composed into the next revolute joint ([`collapse`]); every
/// link assigned, with its fixed attachments, to the body it moves with ([`Graph::parts`]);
/// the parts of each body merged into one rigid body ([`merge`]).
pub fn parse(text: &str, ee: Option<&str>) -> Result<Chain, String> {
    let robot = urdf_rs::read_from_string(text)
        .map_err(|e| format!("not a readable URDF document: {e}"))?;
    let graph = Graph::new(&robot)?;
    let ee_link = graph.end_effector(ee)?;
    let path = graph.path(ee_link)?;
    let collapsed = collapse(graph.root, &path);
    let n = collapsed.joints.len();
    let root = graph.root;
    let bodies = graph.parts(&path, &collapsed.path_links, ee_link, n + 1)?;
    if !(MIN_JOINTS..=MAX_JOINTS).contains(&n) {
        return Err(format!(
            "the chain from '{root}' to '{ee_link}' has {n} revolute joints; supported: {MIN_JOINTS}..={MAX_JOINTS}"
        ));
    }
    let mut descs = Vec::with_capacity(bodies.len());
    let mut collision = Vec::with_capacity(bodies.len());
    let names = std::iter::once(root.to_string()).chain(collapsed.link_names.iter().cloned());
    for (name, parts) in names.zip(&bodies) {
        descs.push(merge(&name, parts)?);
        collision.push(colliders(parts)?);
    }
    let mut descs = descs.into_iter();
    let base = descs.next().ok_or("internal: no base body")?;
    Ok(Chain {
        name: robot.name.clone(),
        base_link: root.to_string(),
        joint_names: collapsed.joint_names,
        link_names: collapsed.link_names,
        ee_link: ee_link.to_string(),
        base,
        joints: collapsed.joints,
        links: descs.collect(),
        end_effector: collapsed.ee_origin,
        collision,
    })
}

/// The collision primitives of one body's parts, in the body's frame.
fn colliders(parts: &[Part]) -> Result<Vec<Collider>, String> {
    let mut out = Vec::new();
    for p in parts {
        for (k, c) in p.link.collision.iter().enumerate() {
            let link = &p.link.name;
            let shape = collision_shape(link, c)?;
            let origin = match p.in_body {
                None => pose_origin(&c.origin),
                Some(tf) => tf.then(&Tf::from_pose(&c.origin)).origin(),
            };
            let name = match &c.name {
                Some(n) if !n.is_empty() => n.clone(),
                _ => format!("{link}/{k}"),
            };
            out.push(Collider {
                name,
                shape,
                origin,
            });
        }
    }
    Ok(out)
}

/// The primitive of a `<collision>` of `link`, or why it is refused.
fn collision_shape(link: &str, c: &urdf_rs::Collision) -> Result<Shape, String> {
    use urdf_rs::Geometry as G;
    let named_capsule = c
        .name
        .as_deref()
        .is_some_and(|n| n.to_ascii_lowercase().contains("capsule"));
    let shape = match &c.geometry {
        G::Sphere { radius } => Shape::Sphere { radius: *radius },
        G::Box { size } => Shape::Box {
            half: size.0.map(|v| 0.5 * v),
        },
        G::Capsule { radius, length } => Shape::Capsule {
            length: *length,
            radius: *radius,
        },
        G::Cylinder { radius, length } if named_capsule => Shape::Capsule {
            length: *length,
            radius: *radius,
        },
        G::Cylinder { .. } => {
            return Err(format!(
                "link '{link}': a <collision> <cylinder> is read only as a capsule: name the <collision> '…capsule…' (or use <capsule>, <box>, <sphere>)"
            ));
        }
        G::Mesh { filename, .. } => {
            return Err(format!(
                "link '{link}': <collision> mesh '{filename}' is not supported: use <sphere>, <box> or a capsule"
            ));
        }
    };
    if !shape.is_valid() {
        return Err(format!(
            "link '{link}': <collision> has a negative or non-finite size ({shape:?})"
        ));
    }
    Ok(shape)
}

/// The link graph of a URDF: links by name, each link's parent joint and child joints,
/// and the one root link.
struct Graph<'a> {
    /// Link names in document order.
    names: Vec<&'a str>,
    links: BTreeMap<&'a str, &'a urdf_rs::Link>,
    parent_of: BTreeMap<&'a str, &'a urdf_rs::Joint>,
    children: BTreeMap<&'a str, Vec<&'a urdf_rs::Joint>>,
    root: &'a str,
    link_count: usize,
    joint_count: usize,
}

impl<'a> Graph<'a> {
    /// Checks names and references and finds the root.
    fn new(robot: &'a urdf_rs::Robot) -> Result<Self, String> {
        let links: BTreeMap<&str, &urdf_rs::Link> =
            robot.links.iter().map(|l| (l.name.as_str(), l)).collect();
        if links.len() != robot.links.len() {
            return Err("two links share a name".into());
        }
        let mut parent_of: BTreeMap<&str, &urdf_rs::Joint> = BTreeMap::new();
        let mut children: BTreeMap<&str, Vec<&urdf_rs::Joint>> = BTreeMap::new();
        for j in &robot.joints {
            for l in [&j.parent.link, &j.child.link] {
                if !links.contains_key(l.as_str()) {
                    return Err(format!("joint '{}' refers to unknown link '{l}'", j.name));
                }
            }
            if parent_of.insert(j.child.link.as_str(), j).is_some() {
                return Err(format!("link '{}' has two parent joints", j.child.link));
            }
            children.entry(j.parent.link.as_str()).or_default().push(j);
        }
        let roots: Vec<&str> = robot
            .links
            .iter()
            .map(|l| l.name.as_str())
            .filter(|n| !parent_of.contains_key(n))
            .collect();
        let root = match roots.as_slice() {
            [r] => *r,
            [] => return Err("no root link (the joints form a cycle)".into()),
            many => return Err(format!("several root links: {}", many.join(", "))),
        };
        Ok(Self {
            names: robot.links.iter().map(|l| l.name.as_str()).collect(),
            links,
            parent_of,
            children,
            root,
            link_count: robot.links.len(),
            joint_count: robot.joints.len(),
        })
    }

    /// The end-effector link: the one named, or the only leaf link.
    fn end_effector(&self, ee: Option<&'a str>) -> Result<&'a str, String> {
        if let Some(e) = ee {
            return match self.links.get_key_value(e) {
                Some((name, _)) => Ok(name),
                None => Err(format!("end-effector link '{e}' is not in the URDF")),
            };
        }
        let leaves: Vec<&str> = self
            .names
            .iter()
            .copied()
            .filter(|n| !self.children.contains_key(n))
            .collect();
        match leaves.as_slice() {
            [l] => Ok(l),
            many => Err(format!(
                "several leaf links ({}); name the end effector (ee_link / --ee)",
                many.join(", ")
            )),
        }
    }

    /// The joints from the root to `ee_link`, root first; revolute and fixed only.
    fn path(&self, ee_link: &str) -> Result<Vec<&'a urdf_rs::Joint>, String> {
        let mut path: Vec<&urdf_rs::Joint> = Vec::new();
        let mut cur = ee_link;
        while let Some(j) = self.parent_of.get(cur) {
            if path.len() > self.joint_count {
                return Err("the joints form a cycle".into());
            }
            path.push(j);
            cur = j.parent.link.as_str();
        }
        path.reverse();
        for j in &path {
            match j.joint_type {
                urdf_rs::JointType::Revolute | urdf_rs::JointType::Fixed => {}
                ref t => {
                    return Err(format!(
                        "joint '{}' is {t:?}: only revolute and fixed joints are supported",
                        j.name
                    ));
                }
            }
        }
        Ok(path)
    }

    /// Every path link and its fixed off-path subtrees, grouped by the body they move
    /// with (`bodies` of them: the root's, then one per revolute joint).
    fn parts(
        &self,
        path: &[&urdf_rs::Joint],
        path_links: &[PathLink<'a>],
        ee_link: &str,
        bodies: usize,
    ) -> Result<Vec<Vec<Part<'a>>>, String> {
        let on_path: Vec<&str> = path.iter().map(|j| j.name.as_str()).collect();
        let mut out: Vec<Vec<Part>> = (0..bodies).map(|_| Vec::new()).collect();
        let mut body_index = 0usize;
        for (k, pl) in path_links.iter().enumerate() {
            if k > 0 && !pl.via_fixed {
                body_index += 1;
            }
            let link = self
                .links
                .get(pl.name)
                .copied()
                .ok_or_else(|| format!("link '{}' missing", pl.name))?;
            let Some(parts) = out.get_mut(body_index) else {
                return Err("internal: body index".into());
            };
            parts.push(Part {
                link,
                in_body: pl.via_fixed.then_some(pl.in_body),
            });
            let beyond_ee = k + 1 == path_links.len();
            self.attachments(pl.name, pl.in_body, &on_path, beyond_ee, ee_link, parts)?;
        }
        Ok(out)
    }

    /// The links fixed (through fixed joints only) to `name` off the path, pushed with
    /// their pose in the body frame; a movable joint there is an error.
    fn attachments(
        &self,
        name: &'a str,
        in_body: Tf,
        on_path: &[&str],
        beyond_ee: bool,
        ee_link: &str,
        parts: &mut Vec<Part<'a>>,
    ) -> Result<(), String> {
        let root = self.root;
        let mut stack: Vec<(&str, Tf)> = vec![(name, in_body)];
        let mut guard = 0usize;
        while let Some((lname, ltf)) = stack.pop() {
            guard += 1;
            if guard > self.link_count + 1 {
                return Err("the joints form a cycle".into());
            }
            for cj in self.children.get(lname).map(Vec::as_slice).unwrap_or(&[]) {
                if on_path.contains(&cj.name.as_str()) {
                    continue;
                }
                if cj.joint_type != urdf_rs::JointType::Fixed {
                    if beyond_ee {
                        return Err(format!(
                            "{:?} joint '{}' moves links beyond the end-effector link '{ee_link}'",
                            cj.joint_type, cj.name
                        ));
                    }
                    return Err(format!(
                        "branching tree: {:?} joint '{}' is not on the chain from '{root}' to '{ee_link}'",
                        cj.joint_type, cj.name
                    ));
                }
                let ctf = ltf.then(&Tf::from_pose(&cj.origin));
                let clink = self
                    .links
                    .get(cj.child.link.as_str())
                    .copied()
                    .ok_or_else(|| format!("link '{}' missing", cj.child.link))?;
                parts.push(Part {
                    link: clink,
                    in_body: Some(ctf),
                });
                stack.push((cj.child.link.as_str(), ctf));
            }
        }
        Ok(())
    }
}

/// A link on the path and where it sits in the body it moves with.
struct PathLink<'a> {
    name: &'a str,
    /// Its frame in the body's frame (identity for the body's own link).
    in_body: Tf,
    /// Reached through a fixed joint (so it belongs to the previous body).
    via_fixed: bool,
}

/// The path with its fixed joints composed away.
struct Collapsed<'a> {
    joints: Vec<JointDesc>,
    joint_names: Vec<String>,
    link_names: Vec<String>,
    /// Every link on the path (root first) with its place in its body.
    path_links: Vec<PathLink<'a>>,
    /// End-effector frame in the last body's frame.
    ee_origin: Origin,
}

/// Composes the fixed joints of the path into the next revolute joint's origin (or into
/// the end-effector frame). Where nothing is composed, the origin passes through untouched.
fn collapse<'a>(root: &'a str, path: &[&'a urdf_rs::Joint]) -> Collapsed<'a> {
    let mut out = Collapsed {
        joints: Vec::new(),
        joint_names: Vec::new(),
        link_names: Vec::new(),
        path_links: vec![PathLink {
            name: root,
            in_body: Tf::identity(),
            via_fixed: false,
        }],
        ee_origin: Origin::IDENTITY,
    };
    // Transform from the current body's frame to the current path link's frame.
    let mut to_link = Tf::identity();
    let mut composed = false;
    for j in path {
        if j.joint_type == urdf_rs::JointType::Fixed {
            to_link = to_link.then(&Tf::from_pose(&j.origin));
            composed = true;
            out.path_links.push(PathLink {
                name: j.child.link.as_str(),
                in_body: to_link,
                via_fixed: true,
            });
            continue;
        }
        let origin = if composed {
            to_link.then(&Tf::from_pose(&j.origin)).origin()
        } else {
            pose_origin(&j.origin)
        };
        let l = &j.limit;
        out.joints.push(JointDesc {
            origin,
            axis: j.axis.xyz.0,
            lower: l.lower,
            upper: l.upper,
            velocity: l.velocity,
        });
        out.joint_names.push(j.name.clone());
        out.link_names.push(j.child.link.clone());
        to_link = Tf::identity();
        composed = false;
        out.path_links.push(PathLink {
            name: j.child.link.as_str(),
            in_body: to_link,
            via_fixed: false,
        });
    }
    if composed {
        out.ee_origin = to_link.origin();
    }
    out
}

/// The mass properties of one body from its parts.
fn merge(body: &str, parts: &[Part]) -> Result<BodyDesc, String> {
    let mut massive = Vec::new();
    for p in parts {
        let m = p.link.inertial.mass.value;
        if !m.is_finite() {
            return Err(format!(
                "link '{}': mass is not a finite number",
                p.link.name
            ));
        }
        if m < 0.0 {
            return Err(format!("link '{}': negative mass {m}", p.link.name));
        }
        if m > 0.0 {
            massive.push(p);
        }
    }
    let inertia_of = |l: &urdf_rs::Link| {
        let i = &l.inertial.inertia;
        Inertia {
            ixx: i.ixx,
            ixy: i.ixy,
            ixz: i.ixz,
            iyy: i.iyy,
            iyz: i.iyz,
            izz: i.izz,
        }
    };
    match massive.as_slice() {
        [] => Err(format!(
            "body '{body}' has no mass (the links moved together by one joint need mass > 0)"
        )),
        [p] if p.in_body.is_none() => Ok(BodyDesc {
            mass: p.link.inertial.mass.value,
            inertial: pose_origin(&p.link.inertial.origin),
            inertia: inertia_of(p.link),
        }),
        many => {
            // Combine: CoM and inertia of every part in the body frame, parallel-axis sum.
            let mut total = 0.0;
            let mut moment = Vec3::zeros();
            let mut items = Vec::new();
            for p in many {
                let tf = p.in_body.unwrap_or_else(Tf::identity);
                let inertial = tf.then(&Tf::from_pose(&p.link.inertial.origin));
                let m = p.link.inertial.mass.value;
                let i = inertia_of(p.link).to_sym().rotated(&inertial.r);
                total += m;
                moment += inertial.t * m;
                items.push((m, inertial.t, i));
            }
            let com = moment / total;
            let mut sum = Sym3::ZERO;
            for (m, c, i) in items {
                sum = sum.add(&i).add(&Sym3::point_mass(m, &(c - com)));
            }
            Ok(BodyDesc {
                mass: total,
                inertial: Origin {
                    xyz: [com.x, com.y, com.z],
                    rpy: [0.0; 3],
                },
                inertia: Inertia {
                    ixx: sum.xx,
                    ixy: sum.xy,
                    ixz: sum.xz,
                    iyy: sum.yy,
                    iyz: sum.yz,
                    izz: sum.zz,
                },
            })
        }
    }
}
