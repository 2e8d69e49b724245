//! The decoding half of a fixed-lag Viterbi, shared by the pitch trackers ([`crate::pyin`],
//! [`crate::shs`]): pick the best final state, then follow the back-pointers that each
//! tracker keeps in a ring of hops. No allocation.

/// Index of the largest score; the first one wins a tie.
pub(crate) fn best_state(delta: &[f32]) -> usize {
    let mut best = 0;
    for (s, &v) in delta.iter().enumerate() {
        if v > delta[best] {
            best = s;
        }
    }
    best
}

/// Backtracks hops `start..end` from `last` (the state at hop `end - 1`) into
/// `path[..end - start]`. `bp[(h % ring) * states + s]` is the predecessor of state `s` at
/// hop `h`.
pub(crate) fn backtrack(
    path: &mut [u16],
    bp: &[u16],
    ring: usize,
    states: usize,
    (start, end): (usize, usize),
    last: usize,
) {
    let mut s = last;
    for h in (start..end).rev() {
        path[h - start] = s as u16;
        if h > start {
            s = bp[(h % ring) * states + s] as usize;
        }
    }
}
