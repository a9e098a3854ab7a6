//! Runtime joint count → the core's const generics.
//!
//! The core fixes `N` (joints) and `K = N − 3` (null-space dimension) at compile time; a
//! URDF decides `N` at run time. [`with_dims!`] instantiates a generic function for every
//! supported `N` (4..=12) and calls the one that matches.

/// `with_dims!(n, f, args...)` calls `f::<N, K>(args...)` for `n = N`, or returns a
/// bad-input error for an unsupported `n`.
#[macro_export]
macro_rules! with_dims {
    ($n:expr, $f:ident, $($arg:expr),* $(,)?) => {
        match $n {
            4 => $f::<4, 1>($($arg),*),
            5 => $f::<5, 2>($($arg),*),
            6 => $f::<6, 3>($($arg),*),
            7 => $f::<7, 4>($($arg),*),
            8 => $f::<8, 5>($($arg),*),
            9 => $f::<9, 6>($($arg),*),
            10 => $f::<10, 7>($($arg),*),
            11 => $f::<11, 8>($($arg),*),
            12 => $f::<12, 9>($($arg),*),
            n => Err($crate::error::CliError::input(format!(
                "robots with {n} joints are not supported (4..=12)"
            ))),
        }
    };
}
