//! The trajectory digest: one 64-bit value that changes if any bit of any sample changes.
//!
//! Owns [`TrajectoryDigest`], a [`Sink`] computing FNV-1a (64-bit) over the little-endian
//! bytes of the IEEE-754 bit pattern of every value of every sample, in order:
//! `t, q1 … qN, qd1 … qdN` for `s = 0 … S`. Host records and the flight image compute the
//! same digest, so a trajectory planned on the ground and one planned in flight can be
//! compared without storing either. (FNV-1a detects accidental changes; it is not a
//! cryptographic hash.)

use crate::rollout::{Sample, Sink};

const OFFSET_BASIS: u64 = 0xcbf2_9ce4_8422_2325;
const PRIME: u64 = 0x0000_0100_0000_01b3;

/// FNV-1a-64 over the bit patterns of a trajectory's samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TrajectoryDigest {
    state: u64,
    samples: u32,
}

impl Default for TrajectoryDigest {
    fn default() -> Self {
        Self::new()
    }
}

impl TrajectoryDigest {
    /// The digest of nothing.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            state: OFFSET_BASIS,
            samples: 0,
        }
    }

    /// Folds in one value's bit pattern (8 bytes, little-endian).
    pub fn push(&mut self, v: f64) {
        for b in v.to_bits().to_le_bytes() {
            self.state = (self.state ^ u64::from(b)).wrapping_mul(PRIME);
        }
    }

    /// Folds in one sample: `t`, then `q`, then `q̇`.
    pub fn push_sample<const N: usize>(&mut self, s: &Sample<N>) {
        self.push(s.t);
        for v in s.q.iter().chain(s.qd.iter()) {
            self.push(*v);
        }
        self.samples = self.samples.saturating_add(1);
    }

    /// The digest so far.
    #[must_use]
    pub fn value(&self) -> u64 {
        self.state
    }

    /// Samples folded in.
    #[must_use]
    pub fn samples(&self) -> u32 {
        self.samples
    }
}

impl<const N: usize> Sink<N> for TrajectoryDigest {
    fn sample(&mut self, s: &Sample<N>) {
        self.push_sample(s);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// FNV-1a-64 reference vectors: "" and "a" (bytes), from the algorithm's authors.
    /// Verifies RL-SIM-REC-004.
    #[test]
    fn fnv1a_reference_values() {
        assert_eq!(TrajectoryDigest::new().value(), 0xcbf2_9ce4_8422_2325);
        let mut d = TrajectoryDigest::new();
        d.state = (d.state ^ u64::from(b'a')).wrapping_mul(PRIME);
        assert_eq!(d.value(), 0xaf63_dc4c_8601_ec8c);
    }

    /// One flipped bit in one sample changes the trajectory digest.
    /// Verifies RL-SIM-REC-004.
    #[test]
    fn one_bit_changes_the_digest() {
        let s = Sample {
            step: 0,
            t: 0.5,
            q: [1.0, -2.0, 3.0, 0.25],
            qd: [0.0; 4],
        };
        let mut a = TrajectoryDigest::new();
        a.push_sample(&s);
        let mut t = s;
        t.q[2] = f64::from_bits(3.0f64.to_bits() ^ 1);
        let mut b = TrajectoryDigest::new();
        b.push_sample(&t);
        assert_ne!(a.value(), b.value());
        assert_eq!(a.samples(), 1);
    }
}
