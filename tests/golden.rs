//! Golden values of spec §8, reproduced to 1e-9.
//!
//! Requirements: RL-MODEL, RL-RNS, RL-LAW, RL-ROLL, RL-POSE, RL-TRUTH, RL-GOLD, RL-PROP
//! (docs/requirements.md).
// Spec values are quoted digit for digit as published.
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::excessive_precision
)]

mod common;
use common::*;
use reactionless::{Frames, Momentum, TruthModel};

/// H~bm row 1 and the H~b diagonal at q₀ equal spec §8 within 1e-9.
/// Verifies RL-MODEL-003, RL-GOLD-001.
#[test]
fn hbm_row1_and_hb_diagonal_at_q0() {
    let robot = robot();
    let m = Momentum::new(&robot, &Frames::new(&robot, &q0()));
    let row1: Vec<f64> = m.hbm.iter().map(|c| c.x).collect();
    assert_close(
        "H~bm row 1",
        &row1,
        &[
            64.21266294418797,
            -0.4380496694554395,
            30.73213929678442,
            0.9460163643963465,
            -0.1445964302854484,
            -2.247395682178883,
            -0.001460087235621470,
        ],
        1e-9,
    );
    assert_close(
        "H~b diagonal",
        &[m.hb.xx, m.hb.yy, m.hb.zz],
        &[662.0334094765462, 551.0167683682856, 831.1288323973174],
        1e-9,
    );
}

/// X_init, the planner-model start pose at q₀, equals spec §8 within 1e-12.
/// Verifies RL-POSE-001, RL-GOLD-001.
#[test]
fn start_pose_x_init() {
    let task = paper_task();
    let p = task.start_pose();
    assert_close(
        "X_init position",
        &p.position,
        &[1.411848994172882, 0.205060966544099, -1.485528094070300],
        1e-12,
    );
    assert_close(
        "X_init quaternion",
        &p.quat_wxyz,
        &[
            0.300972013996329,
            -0.454561275247545,
            -0.247454494060997,
            0.800972013996329,
        ],
        1e-12,
    );
}

/// The rollout of η̂ reproduces spec §8: g, q at s = 1500, q_S and the end pose within
/// 1e-9, f, Φ = 0, max |q̇|.
/// Verifies RL-MODEL-002, RL-RNS-002, RL-RNS-003, RL-LAW-004, RL-ROLL-001, RL-ROLL-004, RL-POSE-001, RL-GOLD-002, RL-GOLD-003, RL-GOLD-004.
#[test]
fn eta_hat_rollout() {
    let task = paper_task();
    let mut q1500 = None;
    let mut grab = |s: &reactionless::Sample<7>| {
        if s.step == 1500 {
            q1500 = Some(s.q);
        }
    };
    let o = task.rollout(&ETA_HAT, &mut grab).unwrap();
    assert!(
        (o.g - 520546.2259291871).abs() <= 1e-9 * 520546.2259291871,
        "g = {:.17e}",
        o.g
    );
    assert_close(
        "q at s = 1500",
        &q1500.unwrap(),
        &[
            -1.556047768194145,
            0.863524151165416,
            -0.075346264824308,
            0.861266744530506,
            -1.765366414699472,
            -1.587408149294870,
            0.514022620456483,
        ],
        1e-9,
    );
    assert_close(
        "q_S",
        &o.q_final,
        &[
            -1.549991144193346,
            1.031769241948451,
            -0.147836243478473,
            0.183638411295843,
            -2.014503126242836,
            -2.619236484771500,
            1.405521444372797,
        ],
        1e-9,
    );
    assert_close(
        "planner-model end position",
        &o.end_pose.position,
        &[2.016688750234721, 0.139968282330467, -1.431900808896781],
        1e-9,
    );
    assert_close(
        "planner-model end quaternion",
        &o.end_pose.quat_wxyz,
        &[
            0.387453398588336,
            0.265456213490997,
            -0.371640973343593,
            0.800809496430704,
        ],
        1e-9,
    );
    assert!((o.f - 3.27e-5).abs() < 0.005e-5, "f = {:e}", o.f);
    assert_eq!(o.phi, 0.0);
    assert!(
        (o.max_abs_qd.to_degrees() - 5.4).abs() < 0.05,
        "max |qd| = {} deg/s",
        o.max_abs_qd.to_degrees()
    );
}

/// Truth model on η̂: 3000 segments, base disturbance 7.27e-4° within 1 %, end pose within
/// 1e-6 of the target.
/// Verifies RL-TRUTH-001, RL-TRUTH-002, RL-TRUTH-004, RL-GOLD-005, RL-PROP-001.
#[test]
fn truth_model_base_disturbance_for_eta_hat() {
    let task = paper_task();
    let mut truth = TruthModel::new(&task, 10);
    task.rollout(&ETA_HAT, &mut truth).unwrap();
    assert_eq!(truth.segments(), 3000);
    let deg = truth.max_angle().to_degrees();
    assert!(
        (deg - 7.27e-4).abs() <= 0.01 * 7.27e-4,
        "base disturbance {deg:e} deg"
    );
    // The task target was made with the true base drift: the truth-model end pose hits it.
    let f_truth = truth.end_pose().unwrap().error_to(task.target()).norm();
    assert!(f_truth < 1e-6, "truth-model f = {f_truth:e}");
}
