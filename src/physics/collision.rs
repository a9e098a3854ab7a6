//! Collision geometry (spec §13): the primitives and the signed distance between two of them.
//!
//! Owns [`Shape`] (sphere, capsule, box: small `Copy` values, sizes in metres),
//! [`Placed`] (a shape at a pose of the inertial or base frame) and [`signed_distance`].
//! Nothing here knows of a robot, a path or a task: callers place the shapes.
//!
//! **The signed distance** `d` is the Euclidean distance between the two solids when they
//! are apart, and minus the penetration depth (the shortest translation that separates
//! them) when they overlap. Each shape is a *core* swept by a ball: a sphere is a point and
//! its radius, a capsule a segment and its radius, a box itself with radius 0. The cores are
//! convex polytopes (a point, a segment, a box), and
//! `d(A, B) = d_core(A, B) − r_A − r_B`, exactly, in both cases:
//! - cores apart: the smallest distance over the pairs of features that can realise it
//!   (a vertex against the other core, an edge against an edge), each in closed form;
//! - cores overlapping (no separating axis among the face normals and edge cross products,
//!   the separating-axis theorem): minus the smallest overlap over those axes, which for
//!   polytopes is the penetration depth;
//! - two cores that are points or segments only: their distance, which is 0 when they cross
//!   (a capsule pair then reports `−(r_A + r_B)`; the penetration depth can be larger).
//!
//! Accuracy: a few ulps of the sizes and coordinates (closed forms, no iteration). Cost: a
//! sphere or capsule pair is one segment–segment distance; a capsule against a box 6 axes,
//! 2 point–box and 12 segment–segment distances; a box pair 15 axes, 16 point–box and 144
//! segment–segment distances. Every loop is over a fixed array.

use crate::geometry::{Mat3, Vec3};

/// Squared length below which a segment is a point and a separating axis is skipped (m²).
const DEGENERATE: f64 = 1e-24;

/// A collision primitive in its own frame (m).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Shape {
    /// A ball of `radius` about the origin.
    Sphere {
        /// Radius (m), ≥ 0.
        radius: f64,
    },
    /// The points within `radius` of the segment from `z = −length/2` to `z = +length/2`.
    Capsule {
        /// Length of the segment (m), ≥ 0 (the cylindrical part; the whole capsule is
        /// `length + 2·radius` long).
        length: f64,
        /// Radius (m), ≥ 0.
        radius: f64,
    },
    /// The box `|x| ≤ half[0]`, `|y| ≤ half[1]`, `|z| ≤ half[2]`.
    Box {
        /// Half extents (m), each ≥ 0.
        half: [f64; 3],
    },
}

impl Shape {
    /// `true` if every size is finite and ≥ 0.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        let ok = |v: f64| v.is_finite() && v >= 0.0;
        match *self {
            Shape::Sphere { radius } => ok(radius),
            Shape::Capsule { length, radius } => ok(length) && ok(radius),
            Shape::Box { half } => half.iter().all(|h| ok(*h)),
        }
    }

    /// Radius of the smallest ball about the shape's origin that contains it (m): the
    /// broad phase's bound.
    #[must_use]
    pub fn bounding_radius(&self) -> f64 {
        match *self {
            Shape::Sphere { radius } => radius,
            Shape::Capsule { length, radius } => 0.5 * length + radius,
            Shape::Box { half } => norm(&Vec3::new(half[0], half[1], half[2])),
        }
    }
}

/// A shape at a pose: its frame's attitude `rot` and origin `pos` in the frame the
/// distance is measured in (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placed {
    /// The primitive.
    pub shape: Shape,
    /// Attitude of the primitive's frame.
    pub rot: Mat3,
    /// Origin of the primitive's frame (m).
    pub pos: Vec3,
}

/// A shape's core (a convex polytope) and the radius that sweeps it.
#[derive(Debug, Clone, Copy)]
enum Core {
    /// A segment from `.0` to `.1` (a point when they coincide).
    Segment(Vec3, Vec3),
    /// A box: centre, attitude (columns are its axes), half extents.
    Cuboid(Vec3, Mat3, Vec3),
}

impl Placed {
    fn core(&self) -> (Core, f64) {
        match self.shape {
            Shape::Sphere { radius } => (Core::Segment(self.pos, self.pos), radius),
            Shape::Capsule { length, radius } => {
                let axis = Vec3::new(self.rot.m13, self.rot.m23, self.rot.m33) * (0.5 * length);
                (Core::Segment(self.pos - axis, self.pos + axis), radius)
            }
            Shape::Box { half } => (
                Core::Cuboid(self.pos, self.rot, Vec3::new(half[0], half[1], half[2])),
                0.0,
            ),
        }
    }
}

/// Signed distance between two placed shapes (m): the gap when apart, minus the
/// penetration depth when they overlap (see the module documentation for the capsule
/// exception). Symmetric in its arguments up to rounding.
///
/// Verifies RL-COLL-001.
///
/// ```
/// use reactionless::collision::{Placed, Shape, signed_distance};
/// use reactionless::geometry::{Mat3, Vec3};
/// let ball = |x: f64| Placed { shape: Shape::Sphere { radius: 0.5 }, rot: Mat3::identity(), pos: Vec3::new(x, 0.0, 0.0) };
/// let plate = Placed { shape: Shape::Box { half: [0.01, 1.0, 1.0] }, rot: Mat3::identity(), pos: Vec3::zeros() };
/// assert!((signed_distance(&ball(2.0), &plate) - 1.49).abs() < 1e-12);
/// assert!((signed_distance(&ball(0.0), &plate) + 0.51).abs() < 1e-12);
/// ```
#[must_use]
pub fn signed_distance(a: &Placed, b: &Placed) -> f64 {
    let ((ca, ra), (cb, rb)) = (a.core(), b.core());
    let d = match (ca, cb) {
        (Core::Segment(p0, p1), Core::Segment(q0, q1)) => segment_segment(&p0, &p1, &q0, &q1),
        (Core::Segment(p0, p1), Core::Cuboid(c, r, h))
        | (Core::Cuboid(c, r, h), Core::Segment(p0, p1)) => {
            let (p0, p1) = (local(&c, &r, &p0), local(&c, &r, &p1));
            segment_box(&p0, &p1, &h)
        }
        (Core::Cuboid(c1, r1, h1), Core::Cuboid(c2, r2, h2)) => {
            // Box 2 in box 1's frame.
            let c = local(&c1, &r1, &c2);
            let r = r1.transpose() * r2;
            box_box(&h1, &c, &r, &h2)
        }
    };
    d - ra - rb
}

/// `p` in the frame of a box at `c` with attitude `r`.
fn local(c: &Vec3, r: &Mat3, p: &Vec3) -> Vec3 {
    r.transpose() * (p - c)
}

fn norm(v: &Vec3) -> f64 {
    libm::sqrt(v.dot(v))
}

/// `x` limited to `[0, 1]` (NaN stays NaN), without `f64::clamp`'s panic path.
#[allow(clippy::manual_clamp, reason = "f64::clamp has a panic path")]
fn clamp01(x: f64) -> f64 {
    let mut x = x;
    if x < 0.0 {
        x = 0.0;
    }
    if x > 1.0 {
        x = 1.0;
    }
    x
}

/// Distance between segments `p0p1` and `q0q1` (m), either possibly a point (Ericson,
/// *Real-Time Collision Detection*, §5.1.9).
fn segment_segment(p0: &Vec3, p1: &Vec3, q0: &Vec3, q1: &Vec3) -> f64 {
    let (d1, d2, r) = (p1 - p0, q1 - q0, p0 - q0);
    let (a, e, f) = (d1.dot(&d1), d2.dot(&d2), d2.dot(&r));
    let (s, t) = if a <= DEGENERATE && e <= DEGENERATE {
        (0.0, 0.0)
    } else if a <= DEGENERATE {
        (0.0, clamp01(f / e))
    } else {
        let c = d1.dot(&r);
        if e <= DEGENERATE {
            (clamp01(-c / a), 0.0)
        } else {
            let b = d1.dot(&d2);
            let denom = a * e - b * b;
            let s = if denom > 0.0 {
                clamp01((b * f - c * e) / denom)
            } else {
                0.0
            };
            let t = (b * s + f) / e;
            if t < 0.0 {
                (clamp01(-c / a), 0.0)
            } else if t > 1.0 {
                (clamp01((b - c) / a), 1.0)
            } else {
                (s, t)
            }
        }
    };
    norm(&((p0 + d1 * s) - (q0 + d2 * t)))
}

/// Signed distance from point `p` to the box `|x_i| ≤ h_i` (m).
fn point_box(p: &Vec3, h: &Vec3) -> f64 {
    let q = p.abs() - h;
    let out = Vec3::new(q.x.max(0.0), q.y.max(0.0), q.z.max(0.0));
    norm(&out) + q.x.max(q.y).max(q.z).min(0.0)
}

/// The 8 corners of the box `|x_i| ≤ h_i`.
fn corners(h: &Vec3) -> [Vec3; 8] {
    let c = |sx: f64, sy: f64, sz: f64| Vec3::new(sx * h.x, sy * h.y, sz * h.z);
    [
        c(-1.0, -1.0, -1.0),
        c(1.0, -1.0, -1.0),
        c(-1.0, 1.0, -1.0),
        c(1.0, 1.0, -1.0),
        c(-1.0, -1.0, 1.0),
        c(1.0, -1.0, 1.0),
        c(-1.0, 1.0, 1.0),
        c(1.0, 1.0, 1.0),
    ]
}

/// The 12 edges of a box as pairs of its [`corners`] (bit `k` of a corner's index is its
/// sign along axis `k`).
const EDGES: [(usize, usize); 12] = [
    (0, 1),
    (2, 3),
    (4, 5),
    (6, 7),
    (0, 2),
    (1, 3),
    (4, 6),
    (5, 7),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// The edges of a box with corners `c`, as segments.
fn edges(c: &[Vec3; 8]) -> [(Vec3, Vec3); 12] {
    EDGES.map(|(i, j)| {
        let z = Vec3::zeros();
        (
            c.get(i).copied().unwrap_or(z),
            c.get(j).copied().unwrap_or(z),
        )
    })
}

/// Overlap of two projections along unit `axis`, or `None` if the axis separates them:
/// `[lo_a, hi_a]` against `[lo_b, hi_b]`; the overlap is the shortest shift of either
/// interval that separates them.
fn overlap(lo_a: f64, hi_a: f64, lo_b: f64, hi_b: f64) -> Option<f64> {
    if lo_a > hi_b || lo_b > hi_a {
        None
    } else {
        Some((hi_a - lo_b).min(hi_b - lo_a))
    }
}

/// The separating-axis test over candidate `axes` (any length; those shorter than
/// [`DEGENERATE`] are skipped): `None` if one separates (`overlap_along` a unit axis is
/// `None`), else the smallest overlap, the penetration depth of two convex polytopes whose
/// face normals and edge cross products the axes are.
fn penetration(
    axes: impl Iterator<Item = Vec3>,
    overlap_along: impl Fn(&Vec3) -> Option<f64>,
) -> Option<f64> {
    let mut depth = f64::INFINITY;
    for axis in axes {
        let n2 = axis.dot(&axis);
        if n2 <= DEGENERATE {
            continue;
        }
        depth = depth.min(overlap_along(&(axis / libm::sqrt(n2)))?);
    }
    Some(depth)
}

/// Signed distance from segment `p0p1` (box frame) to the box `|x_i| ≤ h_i` (m).
fn segment_box(p0: &Vec3, p1: &Vec3, h: &Vec3) -> f64 {
    // Separating axes: the box's face normals and the segment's direction × each of them.
    let d = p1 - p0;
    let e = [Vec3::x(), Vec3::y(), Vec3::z()];
    let axes = e.iter().copied().chain(e.iter().map(|k| d.cross(k)));
    let overlap_along = |n: &Vec3| {
        let rb = h.x * n.x.abs() + h.y * n.y.abs() + h.z * n.z.abs();
        let (s0, s1) = (n.dot(p0), n.dot(p1));
        overlap(s0.min(s1), s0.max(s1), -rb, rb)
    };
    if let Some(depth) = penetration(axes, overlap_along) {
        return -depth;
    }
    let mut best = point_box(p0, h).min(point_box(p1, h));
    for (a, b) in edges(&corners(h)) {
        best = best.min(segment_segment(p0, p1, &a, &b));
    }
    best
}

/// Signed distance between the box `|x_i| ≤ h1_i` and a box of half extents `h2` at `c`
/// with attitude `r`, both in the first box's frame (m).
fn box_box(h1: &Vec3, c: &Vec3, r: &Mat3, h2: &Vec3) -> f64 {
    let e1 = [Vec3::x(), Vec3::y(), Vec3::z()];
    let e2 = [
        r.column(0).into_owned(),
        r.column(1).into_owned(),
        r.column(2).into_owned(),
    ];
    let radius = |h: &Vec3, e: &[Vec3; 3], n: &Vec3| {
        h.x * n.dot(&e[0]).abs() + h.y * n.dot(&e[1]).abs() + h.z * n.dot(&e[2]).abs()
    };
    let crosses = e1.iter().flat_map(|a| e2.iter().map(move |b| a.cross(b)));
    let axes = e1.iter().copied().chain(e2.iter().copied()).chain(crosses);
    let overlap_along = |n: &Vec3| {
        let (r1, r2, s) = (radius(h1, &e1, n), radius(h2, &e2, n), n.dot(c));
        overlap(-r1, r1, s - r2, s + r2)
    };
    if let Some(depth) = penetration(axes, overlap_along) {
        return -depth;
    }
    let ca = corners(h1);
    let cb = corners(h2).map(|p| c + r * p);
    let rt = r.transpose();
    let mut best = f64::INFINITY;
    for p in &ca {
        best = best.min(point_box(&(rt * (p - c)), h2));
    }
    for p in &cb {
        best = best.min(point_box(p, h1));
    }
    let eb = edges(&cb);
    for (a0, a1) in edges(&ca) {
        for (b0, b1) in &eb {
            best = best.min(segment_segment(&a0, &a1, b0, b1));
        }
    }
    best
}
