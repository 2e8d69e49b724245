//! The causal peak picker of one drum class (step 5 of the module docs).

/// Causal peak picker of one class (step 5).
#[derive(Clone, Copy, Debug)]
pub(super) struct Picker {
    armed: bool,
    peak: f32,
    last: Option<usize>,
}

impl Picker {
    pub(super) const NEW: Picker = Picker {
        armed: true,
        peak: 0.0,
        last: None,
    };

    pub(super) fn step(&mut self, i: usize, a: f32, threshold: f32, min_gap: usize) -> bool {
        if !self.armed {
            self.peak = self.peak.max(a);
            if a < threshold || a < 0.5 * self.peak {
                self.armed = true;
            }
        }
        let gap_ok = self.last.is_none_or(|l| i - l >= min_gap);
        if self.armed && a >= threshold && gap_ok {
            self.armed = false;
            self.peak = a;
            self.last = Some(i);
            return true;
        }
        false
    }
}
