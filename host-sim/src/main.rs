//! host-sim: the std host simulator for the reactionless core.
fn main() {}
