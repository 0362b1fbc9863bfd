//! The signs of the pairs' gradients carried from step to step, and the state prints
//! that tell which targets' states did not change.

use super::*;

/// What one channel state contributes to the test "adding column `j` leaves the optimum as
/// it is" ([`ChanState::unchanged_adding`]) of every `j`: the passive columns, their
/// coefficients and the KKT scale, bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Print {
    pub(super) passive: Vec<usize>,
    pub(super) y: Vec<u64>,
    pub(super) hmax: u64,
    pub(super) ysum: u64,
}

impl Print {
    /// The print of an active state.
    pub(super) fn of(st: &ChanState) -> Self {
        let (passive, y, hmax, ysum) = st.kkt_parts();
        Self {
            passive: passive.to_vec(),
            y: y.iter().map(|v| v.to_bits()).collect(),
            hmax: hmax.to_bits(),
            ysum: ysum.to_bits(),
        }
    }

    /// Whether `st` (active) has this print.
    pub(super) fn matches(&self, st: &ChanState) -> bool {
        let (passive, y, hmax, ysum) = st.kkt_parts();
        self.passive == passive
            && self.y.iter().copied().eq(y.iter().map(|v| v.to_bits()))
            && self.hmax == hmax.to_bits()
            && self.ysum == ysum.to_bits()
    }
}

/// The signs of one screened step's gradients, carried to the next step of a greedy run:
/// per candidate and channel, as bits over the materials, the live targets whose optimum
/// may change when the candidate is added (gradient above the KKT threshold), with the
/// basis columns and the states they were decided on.
///
/// On the next basis (these columns and more at the end), a target whose state is the same
/// bit for bit (no new column in its passive set) has the same gradients, summed in the same
/// order (the new columns add exact zeros), against the same threshold: the same signs. So
/// the next step computes the gradients of the other targets only, and those of the carried
/// targets' positive pairs one by one; late in a greedy run 70-90% of the states are the
/// same and one pair in ten is positive.
#[derive(Clone, Debug)]
pub(crate) struct GradSigns {
    pub(super) cols: Vec<usize>,
    /// Per material and channel, the print of its state (`None`: not a live target of an
    /// active channel).
    pub(super) prints: Vec<[Option<Print>; 3]>,
    pub(super) words: usize,
    /// Per candidate (material) and channel, `words` words of bits over the materials.
    pub(super) bits: Vec<u64>,
    /// Per material, whether its rows of `bits` were computed.
    pub(super) has_row: Vec<bool>,
}

impl GradSigns {
    /// The rows of candidate `cand`, channel after channel.
    pub(super) fn rows(&self, cand: usize) -> &[u64] {
        &self.bits[cand * 3 * self.words..(cand + 1) * 3 * self.words]
    }
}
