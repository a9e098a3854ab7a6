#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]
//! `host_sim::plots::write_plots`: every figure as PNG and SVG, with the expected sizes and
//! labels; bad input is an error and writes nothing.
//!
//! Requirements: RL-SIM-PLOT (docs/requirements.md).

use host_sim::plots::{PlotData, write_plots};
use std::path::Path;

/// 3 joints, 200 samples over 2 s; base angle ~1e-4 deg; optional C-PSO history.
fn data(with_history: bool) -> PlotData {
    let n = 200;
    let t: Vec<f64> = (0..n).map(|i| 2.0 * i as f64 / (n - 1) as f64).collect();
    let q: Vec<Vec<f64>> = t
        .iter()
        .map(|&t| vec![0.5 * (t).sin(), -0.3 + 0.2 * t, 0.1 * (3.0 * t).cos()])
        .collect();
    let qd: Vec<Vec<f64>> = t
        .iter()
        .map(|&t| vec![0.5 * t.cos(), 0.2, -0.3 * (3.0 * t).sin()])
        .collect();
    let ee: Vec<[f64; 3]> = t
        .iter()
        .map(|&t| [1.0 + 0.1 * t, 0.2 * t.sin(), 0.5 - 0.05 * t])
        .collect();
    let base_angle_deg: Vec<f64> = t.iter().map(|&t| 2e-4 * t + 1e-4 * t.sin()).collect();
    PlotData {
        joint_names: vec!["shoulder".into(), "elbow".into(), "wrist".into()],
        t,
        q,
        qd,
        lower: vec![-1.0, -0.5, -0.4],
        upper: vec![1.0, 0.5, 0.4],
        qd_limit: vec![0.6, 0.3, 0.4],
        ee,
        target: [1.2, 0.15, 0.4],
        base_angle_deg,
        best_f_history: with_history.then(|| {
            (0..50)
                .map(|k| 0.3 * (-0.2 * k as f64).exp() + 1e-5)
                .collect()
        }),
        tolerance: 0.05,
        first_hit: with_history.then_some(10),
        base_limit_deg: 0.01,
        stamp: "test task · seed 1 · multistart · host-sim test".into(),
    }
}

/// Width and height from a PNG's IHDR chunk (after checking the signature).
fn png_size(path: &Path) -> (u32, u32) {
    let bytes = std::fs::read(path).unwrap();
    assert!(bytes.len() > 2000, "{} is tiny", path.display());
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{}", path.display());
    assert_eq!(&bytes[12..16], b"IHDR");
    let w = u32::from_be_bytes(bytes[16..20].try_into().unwrap());
    let h = u32::from_be_bytes(bytes[20..24].try_into().unwrap());
    (w, h)
}

const FIGURES: [(&str, (u32, u32), &[&str]); 5] = [
    (
        "joints",
        (1000, 600),
        &[
            "position in range",
            "time (s)",
            "shoulder",
            "wrist",
            "limits",
            "test task",
        ],
    ),
    (
        "joint_rates",
        (1000, 600),
        &["rate in range", "time (s)", "elbow", "limits"],
    ),
    (
        "ee_path",
        (1500, 540),
        &["x (m)", "y (m)", "z (m)", "target"],
    ),
    (
        "base_attitude",
        (1000, 600),
        &["base rotation (deg)", "time (s)", "requirement 0.01"],
    ),
    (
        "convergence",
        (1000, 600),
        &["best f (m, rad)", "rollouts", "σ_e = 0.05", "success"],
    ),
];

fn check(dir: &Path, written: &[String], figures: &[(&str, (u32, u32), &[&str])]) {
    let mut expected = Vec::new();
    for (name, size, labels) in figures {
        let png = format!("{name}.png");
        let svg = format!("{name}.svg");
        assert_eq!(png_size(&dir.join(&png)), *size, "{png}");
        let text = std::fs::read_to_string(dir.join(&svg)).unwrap();
        assert!(text.contains("<svg"), "{svg}");
        for label in *labels {
            assert!(text.contains(label), "{svg} lacks {label:?}");
        }
        expected.push(png);
        expected.push(svg);
    }
    assert_eq!(written, expected.as_slice());
    let mut on_disk: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    on_disk.sort();
    expected.sort();
    assert_eq!(on_disk, expected);
}

/// With a C-PSO history all five figures are written, PNG and SVG, at their sizes and
/// labelled, nothing else.
/// Verifies RL-SIM-PLOT-001.
#[test]
fn writes_all_figures_with_history() {
    let dir = tempfile::tempdir().unwrap();
    let written = write_plots(dir.path(), &data(true)).unwrap();
    check(dir.path(), &written, &FIGURES);
}

/// Without a history the convergence figure is left out and the other four are written.
/// Verifies RL-SIM-PLOT-001.
#[test]
fn skips_convergence_without_history() {
    let dir = tempfile::tempdir().unwrap();
    let written = write_plots(dir.path(), &data(false)).unwrap();
    check(dir.path(), &written, &FIGURES[..4]);
}

/// NaN and infinite samples, limits and history entries are left out; every figure is still
/// written.
/// Verifies RL-SIM-PLOT-002.
#[test]
fn non_finite_samples_are_skipped() {
    let mut d = data(true);
    d.q[10][1] = f64::NAN;
    d.qd[20][0] = f64::INFINITY;
    d.ee[0] = [f64::NAN; 3];
    d.base_angle_deg[199] = f64::NEG_INFINITY;
    d.lower[2] = f64::NEG_INFINITY;
    d.upper[2] = f64::INFINITY;
    if let Some(h) = d.best_f_history.as_mut() {
        h[3] = 0.0;
        h[4] = f64::NAN;
    }
    let dir = tempfile::tempdir().unwrap();
    let written = write_plots(dir.path(), &d).unwrap();
    check(dir.path(), &written, &FIGURES);
}

/// One sample, constant values and a single generation still plot.
/// Verifies RL-SIM-PLOT-002.
#[test]
fn degenerate_ranges_still_plot() {
    // One sample, constant everything, a single generation.
    let mut d = data(true);
    d.t.truncate(1);
    d.q.truncate(1);
    d.qd.truncate(1);
    d.ee.truncate(1);
    d.target = d.ee[0];
    d.base_angle_deg = vec![0.0];
    d.best_f_history = Some(vec![0.25]);
    let dir = tempfile::tempdir().unwrap();
    write_plots(dir.path(), &d).unwrap();
}

/// Empty or mismatched data, no joints, a bad history or nothing finite: an exit-2 error,
/// nothing written.
/// Verifies RL-SIM-PLOT-003.
#[test]
fn bad_input_is_an_error_and_writes_nothing() {
    let cases: Vec<(&str, PlotData)> = vec![
        ("empty", {
            let mut d = data(true);
            d.t.clear();
            d.q.clear();
            d.qd.clear();
            d.ee.clear();
            d.base_angle_deg.clear();
            d
        }),
        ("short q", {
            let mut d = data(false);
            d.q.pop();
            d
        }),
        ("short qd row", {
            let mut d = data(false);
            d.qd[7].pop();
            d
        }),
        ("missing limit", {
            let mut d = data(false);
            d.upper.pop();
            d
        }),
        ("no joints", {
            let mut d = data(false);
            d.joint_names.clear();
            d
        }),
        ("empty history", {
            let mut d = data(false);
            d.best_f_history = Some(Vec::new());
            d
        }),
        ("nothing finite", {
            let mut d = data(false);
            d.base_angle_deg = vec![f64::NAN; d.t.len()];
            d
        }),
        ("no positive f", {
            let mut d = data(false);
            d.best_f_history = Some(vec![0.0, -1.0]);
            d
        }),
    ];
    for (what, d) in cases {
        let dir = tempfile::tempdir().unwrap();
        let err = write_plots(dir.path(), &d).unwrap_err();
        assert_eq!(err.code, host_sim::error::EXIT_BAD_INPUT, "{what}");
        assert!(err.message.starts_with("writing plots: "), "{what}: {err}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "{what}");
    }
}

/// A missing output directory is an exit-2 error.
/// Verifies RL-SIM-PLOT-003.
#[test]
fn missing_directory_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let err = write_plots(&dir.path().join("absent"), &data(false)).unwrap_err();
    assert_eq!(err.code, host_sim::error::EXIT_BAD_INPUT);
}
