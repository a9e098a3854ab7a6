#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]
//! `host_sim::plots`: every figure as PNG and SVG, with the expected sizes and labels;
//! values in degrees and deg/s with units on the axes, each joint's limits drawn and
//! labelled with their values, the base attitude's components beside its magnitude and
//! scaled to the data, the dispersion CDFs titled for a reader with their nominal and
//! limit; bad input is an error and writes nothing. What is drawn is read back from the
//! SVGs: their `<text>` elements, and the dashed polylines of the limits.
//!
//! Requirements: RL-SIM-PLOT (docs/requirements.md).

use host_sim::plots::{Cdf, PlotData, RetimePlotData, write_cdfs, write_plots, write_retime_data};
use std::collections::BTreeMap;
use std::path::Path;

/// The base rotation axis of the test data (unit).
const AXIS: [f64; 3] = [0.6, 0.0, 0.8];

/// 3 joints, 200 samples over 2 s; base angle ~1e-4 deg about [`AXIS`]; optional C-PSO
/// history.
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
    let base_wxyz = base_angle_deg.iter().map(|&a| quat(a)).collect();
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
        base_wxyz,
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

/// The unit quaternion of a rotation by `deg` about [`AXIS`].
fn quat(deg: f64) -> [f64; 4] {
    let h = 0.5 * deg.to_radians();
    [
        h.cos(),
        AXIS[0] * h.sin(),
        AXIS[1] * h.sin(),
        AXIS[2] * h.sin(),
    ]
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

/// The figures of [`data`]: name, size and texts each SVG must contain.
const FIGURES: [(&str, (u32, u32), &[&str]); 5] = [
    (
        "joints",
        // 3 joints: 2 × 2 panels of 480 × 300, 60 px of title and stamp.
        (960, 660),
        &[
            "Joint angles (deg)",
            "angle (deg)",
            "time (s)",
            "shoulder",
            "wrist",
            // ±1 rad and ±0.5 rad (the wrist's are infinite in one test).
            "limits ±57.3 deg",
            "limits ±28.65 deg",
            "test task · seed 1 · multistart",
        ],
    ),
    (
        "joint_rates",
        (960, 660),
        &[
            "Joint rates (deg/s)",
            "rate (deg/s)",
            "time (s)",
            "elbow",
            // 0.6, 0.3 and 0.4 rad/s.
            "limits ±34.38 deg/s",
            "limits ±17.19 deg/s",
            "limits ±22.92 deg/s",
            // The elbow turns at 0.2 rad/s throughout: 2/3 of its limit.
            "elbow: peak 11.46 deg/s (67% of its limit)",
            "test task",
        ],
    ),
    (
        "ee_path",
        (1500, 540),
        &["x (m)", "y (m)", "z (m)", "target", "test task"],
    ),
    (
        "base_attitude",
        (1500, 600),
        &[
            "base rotation (deg)",
            "|θ| (deg)",
            "time (s)",
            "θx",
            "θy",
            "θz",
            "|θ|",
            "requirement ≤ 0.01 deg",
            "log scale",
            "test task",
        ],
    ),
    (
        "convergence",
        (1000, 600),
        &[
            "best f (m, rad)",
            "rollouts",
            "σ_e = 0.05",
            "success",
            "test task",
        ],
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
    d.base_wxyz[150] = [f64::NAN; 4];
    d.base_wxyz[151] = [0.0; 4];
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
    d.base_wxyz = vec![[1.0, 0.0, 0.0, 0.0]];
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
            d.base_wxyz.clear();
            d
        }),
        ("short base_wxyz", {
            let mut d = data(false);
            d.base_wxyz.pop();
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

// --- reading what was drawn back from an SVG ----------------------------------------------

/// The texts of an SVG's `<text>` elements.
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            let body = t.split_once('>')?.1;
            Some(body.split("</text>").next()?.trim().to_string())
        })
        .collect()
}

/// The points of every `<polyline>` drawn with `stroke` (`#RRGGBB`) and `width`.
fn polylines(svg: &str, stroke: &str, width: u32) -> Vec<Vec<(i64, i64)>> {
    let want = format!("stroke=\"{stroke}\" stroke-width=\"{width}\"");
    svg.split("<polyline")
        .skip(1)
        .filter_map(|p| {
            let el = p.split("/>").next()?;
            if !el.contains(&want) {
                return None;
            }
            let pts = el.split("points=\"").nth(1)?.split('"').next()?;
            Some(
                pts.split_whitespace()
                    .filter_map(|xy| {
                        let (x, y) = xy.split_once(',')?;
                        Some((x.parse().ok()?, y.parse().ok()?))
                    })
                    .collect(),
            )
        })
        .collect()
}

/// The limit lines (dashed, red, 1 px) of an SVG: `(panel column, level)` of each line
/// of at least 10 dashes, horizontal (`level` = y) or vertical (`level` = x). The legend's
/// sample of a limit line has fewer dashes and is not counted.
fn limit_lines(svg: &str, panel_width: i64, horizontal: bool) -> Vec<(i64, i64)> {
    let mut dashes: BTreeMap<(i64, i64), usize> = BTreeMap::new();
    for p in polylines(svg, "#D62728", 1) {
        let (Some(&a), Some(&b)) = (p.first(), p.last()) else {
            continue;
        };
        let key = if horizontal && a.1 == b.1 && a.0 != b.0 {
            (a.0 / panel_width, a.1)
        } else if !horizontal && a.0 == b.0 && a.1 != b.1 {
            (a.0 / panel_width, a.0)
        } else {
            continue;
        };
        *dashes.entry(key).or_default() += 1;
    }
    dashes
        .into_iter()
        .filter(|&(_, n)| n >= 10)
        .map(|(k, _)| k)
        .collect()
}

/// The vertical extent (px) of the plot area of the panel whose grid lines start at
/// `x_from..x_to`: a vertical grid line's length.
fn plot_height(svg: &str, x_from: i64, x_to: i64) -> i64 {
    svg.split("<line")
        .skip(1)
        .filter_map(|l| {
            let el = l.split("/>").next()?;
            if !el.contains("stroke=\"#C8C8C8\"") {
                return None;
            }
            let num = |k: &str| -> Option<i64> {
                el.split(&format!("{k}=\""))
                    .nth(1)?
                    .split('"')
                    .next()?
                    .parse()
                    .ok()
            };
            let (x1, y1, x2, y2) = (num("x1")?, num("y1")?, num("x2")?, num("y2")?);
            (x1 == x2 && (x_from..x_to).contains(&x1)).then_some((y1 - y2).abs())
        })
        .max()
        .unwrap_or(0)
}

/// Joint angles and rates are drawn in degrees, one panel per joint, each with its two
/// limits as dashed lines at the limits' values; a joint without finite limits gets none
/// and says so.
/// Verifies RL-SIM-PLOT-004.
#[test]
fn each_joint_is_drawn_in_degrees_against_its_limits() {
    let dir = tempfile::tempdir().unwrap();
    write_plots(dir.path(), &data(false)).unwrap();
    for name in ["joints", "joint_rates"] {
        let svg = std::fs::read_to_string(dir.path().join(format!("{name}.svg"))).unwrap();
        // 3 panels × 2 limits, each at its own height within its panel.
        assert_eq!(limit_lines(&svg, 480, true).len(), 6, "{name}");
        let t = texts(&svg);
        for joint in ["shoulder", "elbow", "wrist"] {
            assert!(t.iter().any(|s| s.starts_with(joint)), "{name}: {joint}");
        }
        assert!(!t.iter().any(|s| s.contains("in range")), "{name}");
    }
    // The wrist's position limits are infinite: 2 panels with limits, the wrist none.
    let mut d = data(false);
    d.lower[2] = f64::NEG_INFINITY;
    d.upper[2] = f64::INFINITY;
    let dir = tempfile::tempdir().unwrap();
    write_plots(dir.path(), &d).unwrap();
    let svg = std::fs::read_to_string(dir.path().join("joints.svg")).unwrap();
    assert_eq!(limit_lines(&svg, 480, true).len(), 4);
    assert!(texts(&svg).iter().any(|s| s == "no finite limits"));
    // The wrist moves between 0.1·cos(6) and 0.1 rad: its title gives that in degrees.
    assert!(
        texts(&svg)
            .iter()
            .any(|s| s.starts_with("wrist: between ") && s.ends_with(" and 5.73 deg")),
        "{:?}",
        texts(&svg)
    );
}

/// The base attitude shows the rotation vector's three components and its magnitude on
/// an axis fitted to the data (the magnitude spans most of the plot's height, not the
/// bottom tenth below a far requirement), and the magnitude against the requirement on a
/// log axis; the requirement comes onto the linear axis once the data reaches half of it.
/// Verifies RL-SIM-PLOT-005.
#[test]
fn base_attitude_shows_components_and_uses_the_plot() {
    let dir = tempfile::tempdir().unwrap();
    write_plots(dir.path(), &data(false)).unwrap();
    let svg = std::fs::read_to_string(dir.path().join("base_attitude.svg")).unwrap();
    // Left panel: x < 750 px. The magnitude is black, dotted, 2 px.
    let ys: Vec<i64> = polylines(&svg, "#000000", 2)
        .into_iter()
        .flatten()
        .filter(|p| p.0 < 750)
        .map(|p| p.1)
        .collect();
    let span = ys.iter().max().unwrap() - ys.iter().min().unwrap();
    let height = plot_height(&svg, 0, 750);
    assert!(height > 300, "{height}");
    assert!(
        span as f64 >= 0.8 * height as f64,
        "|θ| spans {span} of {height} px"
    );
    // The components: θx and θz along the axis, θy zero (blue, orange, green, 2 px).
    for colour in ["#1F77B4", "#FF7F0E", "#2CA02C"] {
        assert!(!polylines(&svg, colour, 2).is_empty(), "{colour}");
    }
    // 0.01 deg is 20 times the largest angle: on the log panel only.
    let lines = limit_lines(&svg, 750, true);
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert_eq!(lines[0].0, 1);
    assert!(texts(&svg).iter().any(|s| s.contains("off this scale")));

    // Data past the requirement: the requirement on both panels.
    let mut d = data(false);
    d.base_angle_deg.iter_mut().for_each(|a| *a *= 40.0);
    d.base_wxyz = d.base_angle_deg.iter().map(|&a| quat(a)).collect();
    let dir = tempfile::tempdir().unwrap();
    write_plots(dir.path(), &d).unwrap();
    let svg = std::fs::read_to_string(dir.path().join("base_attitude.svg")).unwrap();
    let lines = limit_lines(&svg, 750, true);
    assert_eq!(lines.iter().map(|l| l.0).collect::<Vec<_>>(), [0, 1]);
    assert!(
        texts(&svg)
            .iter()
            .any(|s| s.starts_with("largest 0.01964 deg (196% of the requirement)")),
        "{:?}",
        texts(&svg)
    );
}

/// A dispersion CDF is titled for a reader with its unit, its axis carries the unit, its
/// limit is a vertical dashed line labelled with value and unit, and the nominal value is
/// marked; the raw column name appears only in the file name.
/// Verifies RL-SIM-PLOT-006.
#[test]
fn cdfs_have_human_titles_units_limit_and_nominal() {
    let dir = tempfile::tempdir().unwrap();
    let values: Vec<f64> = (0..100).map(|k| 1e-4 * f64::from(k)).collect();
    let series = [
        Cdf {
            name: "base_disturbance_deg",
            title: "Base disturbance",
            unit: "deg",
            values: values.clone(),
            limit: Some(0.005),
            nominal: Some(0.002),
        },
        Cdf {
            name: "position_error_m",
            title: "End-effector position error",
            unit: "m",
            values,
            limit: None,
            nominal: Some(0.003),
        },
    ];
    let written = write_cdfs(dir.path(), &series, "mc · 100 samples · seed 7").unwrap();
    assert_eq!(
        written,
        [
            "cdf_base_disturbance_deg.png",
            "cdf_base_disturbance_deg.svg",
            "cdf_position_error_m.png",
            "cdf_position_error_m.svg"
        ]
    );
    let svg = std::fs::read_to_string(dir.path().join("cdf_base_disturbance_deg.svg")).unwrap();
    let t = texts(&svg);
    for want in [
        "Base disturbance (deg): cumulative distribution",
        "base disturbance (deg)",
        "fraction of samples ≤ x",
        // 0.0000 .. 0.0050: 51 of 100 samples.
        "requirement ≤ 0.005 deg: 51% of samples meet it",
        "nominal (undispersed) 0.002 deg",
        "mc · 100 samples · seed 7",
    ] {
        assert!(t.iter().any(|s| s == want), "lacks {want:?}: {t:?}");
    }
    assert!(
        !t.iter().any(|s| s.contains("base_disturbance_deg")),
        "{t:?}"
    );
    assert_eq!(limit_lines(&svg, 900, false).len(), 1);
    // The nominal: dotted, green, 2 px, vertical.
    let nominal = polylines(&svg, "#2CA02C", 2);
    assert!(
        nominal
            .iter()
            .filter(|p| p[0].0 == p[p.len() - 1].0)
            .count()
            >= 10
    );
    let svg = std::fs::read_to_string(dir.path().join("cdf_position_error_m.svg")).unwrap();
    let t = texts(&svg);
    assert!(
        t.iter().any(|s| s == "end-effector position error (m)"),
        "{t:?}"
    );
    assert!(
        t.iter().any(|s| s == "nominal (undispersed) 0.003 m"),
        "{t:?}"
    );
    assert!(limit_lines(&svg, 900, false).is_empty());
    // A name that is not a file name is refused, and nothing is written.
    let dir = tempfile::tempdir().unwrap();
    let bad = Cdf {
        name: "../x",
        title: "X",
        unit: "m",
        values: vec![1.0],
        limit: None,
        nominal: None,
    };
    assert!(write_cdfs(dir.path(), &[bad], "").is_err());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

/// A re-timed trajectory's rates and accelerations are drawn in deg/s and deg/s², one
/// panel per joint with its limits.
/// Verifies RL-SIM-RETIME-002.
#[test]
fn retimed_figures_are_in_degrees_against_the_limits() {
    let d = data(false);
    let r = RetimePlotData {
        joint_names: d.joint_names.clone(),
        t: d.t.clone(),
        qd: d.qd.clone(),
        qdd: d
            .qd
            .iter()
            .map(|r| r.iter().map(|v| 0.5 * v).collect())
            .collect(),
        qd_limit: d.qd_limit.clone(),
        qdd_limit: vec![0.35; 3],
        stamp: "test task · retimed".into(),
    };
    let dir = tempfile::tempdir().unwrap();
    let written = write_retime_data(dir.path(), &r).unwrap();
    assert_eq!(written.len(), 4);
    for (name, want) in [
        ("retimed_rates", ["rate (deg/s)", "limits ±34.38 deg/s"]),
        (
            "retimed_accelerations",
            ["acceleration (deg/s²)", "limits ±20.05 deg/s²"],
        ),
    ] {
        let svg = std::fs::read_to_string(dir.path().join(format!("{name}.svg"))).unwrap();
        let t = texts(&svg);
        for w in want {
            assert!(t.iter().any(|s| s == w), "{name} lacks {w:?}: {t:?}");
        }
        assert_eq!(limit_lines(&svg, 480, true).len(), 6, "{name}");
    }
    let mut bad = r.clone();
    bad.qdd[3].pop();
    assert!(write_retime_data(tempfile::tempdir().unwrap().path(), &bad).is_err());
}
