//! The signed distance of spec §13 against closed cases and against an independent bound.
//!
//! For two convex solids, the signed distance is the largest separation along a unit
//! direction `n`: `max_n (min_B n·x − max_A n·x)`, which is the gap when apart and minus the
//! penetration depth when they overlap. Support functions give that separation exactly for
//! spheres, capsules and boxes, so any set of directions gives a lower bound, and a search
//! over directions approaches the value from below.
//!
//! Requirements: RL-COLL (docs/requirements.md).

#![allow(clippy::indexing_slicing, missing_docs)]

use proptest::prelude::*;
use reactionless::collision::{Placed, Shape, signed_distance};
use reactionless::geometry::{Vec3, rpy_matrix};

fn at(shape: Shape, rpy: [f64; 3], pos: [f64; 3]) -> Placed {
    Placed {
        shape,
        rot: rpy_matrix(rpy),
        pos: Vec3::new(pos[0], pos[1], pos[2]),
    }
}

/// `max_{x ∈ S} n·x`.
fn support(s: &Placed, n: &Vec3) -> f64 {
    match s.shape {
        Shape::Sphere { radius } => n.dot(&s.pos) + radius,
        Shape::Capsule { length, radius } => {
            let axis: Vec3 = s.rot.column(2).into_owned() * (0.5 * length);
            n.dot(&s.pos) + n.dot(&axis).abs() + radius
        }
        Shape::Box { half } => {
            n.dot(&s.pos)
                + (0..3)
                    .map(|k| half[k] * n.dot(&s.rot.column(k)).abs())
                    .sum::<f64>()
        }
    }
}

fn separation(a: &Placed, b: &Placed, n: &Vec3) -> f64 {
    let n = n.normalize();
    -support(b, &-n) - support(a, &n)
}

/// The largest separation found over a Fibonacci sphere of directions, then refined by a
/// shrinking random search around the best one: a lower bound on the signed distance.
fn separation_bound(a: &Placed, b: &Placed) -> f64 {
    let m = 4000;
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut best = (f64::NEG_INFINITY, Vec3::x());
    for i in 0..m {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / m as f64;
        let r = (1.0 - z * z).sqrt();
        let n = Vec3::new(
            r * (golden * i as f64).cos(),
            r * (golden * i as f64).sin(),
            z,
        );
        let s = separation(a, b, &n);
        if s > best.0 {
            best = (s, n);
        }
    }
    let mut step = 0.05;
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    while step > 1e-10 {
        let mut improved = false;
        for _ in 0..100 {
            let n = (best.1 + Vec3::new(next(), next(), next()) * step).normalize();
            let s = separation(a, b, &n);
            if s > best.0 {
                best = (s, n);
                improved = true;
            }
        }
        if !improved {
            step *= 0.5;
        }
    }
    best.0
}

fn shape() -> impl Strategy<Value = Shape> {
    prop_oneof![
        (0.0..0.5f64).prop_map(|radius| Shape::Sphere { radius }),
        (0.0..1.5f64, 0.0..0.4f64).prop_map(|(length, radius)| Shape::Capsule { length, radius }),
        (0.0..0.8f64, 0.0..0.8f64, 0.0..0.8f64)
            .prop_map(|(x, y, z)| Shape::Box { half: [x, y, z] }),
    ]
}

fn placed() -> impl Strategy<Value = Placed> {
    (
        shape(),
        prop::array::uniform3(-3.2..3.2f64),
        prop::array::uniform3(-1.5..1.5f64),
    )
        .prop_map(|(s, rpy, pos)| at(s, rpy, pos))
}

fn is_capsule_like(s: &Shape) -> bool {
    !matches!(s, Shape::Box { .. })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1000))]

    /// The signed distance is never below the best separating direction
    /// (it is the largest separation), and a direction search comes within 1e-2 m of it (the search, not the
    /// distance, limits this: exactness is the closed cases' and the coal checker's job),
    /// apart or overlapping, for every pair of primitives. Two capsule-like cores that
    /// cross are the documented exception (the value is `−(r_A + r_B)`, above `−depth`).
    #[test]
    fn signed_distance_is_the_largest_separation(a in placed(), b in placed()) {
        let d = signed_distance(&a, &b);
        let lb = separation_bound(&a, &b);
        prop_assert!(d >= lb - 1e-9, "d {d} below a separation {lb}");
        let crossing = is_capsule_like(&a.shape) && is_capsule_like(&b.shape) && d < 0.0;
        if !crossing {
            prop_assert!(d - lb <= 1e-2, "d {d} above the best separation {lb}");
        }
        let back = signed_distance(&b, &a);
        prop_assert!((d - back).abs() <= 1e-12 * (1.0 + d.abs()), "not symmetric: {d} {back}");
    }
}

/// Closed cases: faces, a vertex, an edge, overlapping boxes, a capsule across and
/// through a box, spheres and parallel capsules.
/// Verifies RL-COLL-001.
#[test]
fn closed_cases() {
    let id = [0.0; 3];
    let unit_box = Shape::Box {
        half: [0.5, 0.5, 0.5],
    };
    // Face to face, vertex to face, edge to edge.
    let b = at(unit_box, id, [0.0; 3]);
    assert!((signed_distance(&b, &at(unit_box, id, [1.25, 0.2, -0.1])) - 0.25).abs() < 1e-15);
    let q = std::f64::consts::FRAC_PI_4;
    let diag = at(unit_box, [0.0, 0.0, q], [1.0, 0.0, 0.0]);
    let expect = 1.0 - 0.5 - 0.5 * 2f64.sqrt();
    assert!((signed_distance(&b, &diag) - expect).abs() < 1e-15);
    // Overlapping boxes: depth along x.
    assert!((signed_distance(&b, &at(unit_box, id, [0.9, 0.0, 0.0])) + 0.1).abs() < 1e-15);
    // A capsule lying across the box's top face, 0.3 m above it; then through the box at
    // z = 0.1: its segment must rise 0.4 m to leave the box, and its radius adds 0.1 m.
    let across = |z: f64| {
        let capsule = Shape::Capsule {
            length: 4.0,
            radius: 0.1,
        };
        at(capsule, [0.0, q * 2.0, 0.0], [0.0, 0.0, z])
    };
    assert!((signed_distance(&b, &across(0.9)) - 0.3).abs() < 1e-15);
    assert!((signed_distance(&b, &across(0.1)) + 0.5).abs() < 1e-15);
    // Sphere pair, capsule pair (parallel).
    let s = |x: f64| at(Shape::Sphere { radius: 0.25 }, id, [x, 0.0, 0.0]);
    assert!((signed_distance(&s(0.0), &s(1.0)) - 0.5).abs() < 1e-15);
    let c = |y: f64| {
        at(
            Shape::Capsule {
                length: 1.0,
                radius: 0.1,
            },
            id,
            [0.0, y, 0.0],
        )
    };
    assert!((signed_distance(&c(0.0), &c(0.5)) - 0.3).abs() < 1e-15);
}

/// Sizes must be finite and ≥ 0 (a zero size is a plate, a point or a segment).
/// Verifies RL-COLL-002.
#[test]
fn validity() {
    assert!(
        Shape::Box {
            half: [0.0, 1.0, 1.0]
        }
        .is_valid()
    );
    assert!(!Shape::Sphere { radius: -1.0 }.is_valid());
    assert!(
        !Shape::Capsule {
            length: f64::NAN,
            radius: 1.0
        }
        .is_valid()
    );
    assert!(
        !Shape::Box {
            half: [1.0, f64::INFINITY, 1.0]
        }
        .is_valid()
    );
}
