//! Interpolated position mode: a FIFO of position set-points, one consumed per SYNC, with linear
//! interpolation from the current demand to it over one interpolation period (AKD 6.9).

use std::collections::VecDeque;

/// The set-point buffer and the segment being interpolated.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Interpolator {
    buffer: VecDeque<i32>,
    /// Interpolation enabled (controlword bit 4 in mode 7).
    pub(crate) enabled: bool,
    from: f64,
    to: f64,
    /// Time into the current segment, µs.
    elapsed_us: u64,
    period_us: u32,
    /// A SYNC found the buffer empty.
    pub(crate) underflow: bool,
}

impl Interpolator {
    pub(crate) fn new() -> Self {
        Interpolator {
            buffer: VecDeque::new(),
            enabled: false,
            from: 0.0,
            to: 0.0,
            elapsed_us: 0,
            period_us: 0,
            underflow: false,
        }
    }

    /// Queues a set-point; false when `capacity` set-points are already waiting.
    pub(crate) fn push(&mut self, sp: i32, capacity: usize) -> bool {
        if self.buffer.len() >= capacity.max(1) {
            return false;
        }
        self.buffer.push_back(sp);
        true
    }

    pub(crate) fn len(&self) -> usize {
        self.buffer.len()
    }

    pub(crate) fn clear(&mut self) {
        self.buffer.clear();
    }

    /// Stands still at `p` (enable, halt, mode entry).
    pub(crate) fn hold(&mut self, p: f64) {
        self.from = p;
        self.to = p;
        self.elapsed_us = 0;
        self.period_us = 0;
    }

    /// A SYNC: starts the next segment from `p` towards the next set-point, passed through
    /// `limit` (the software limits). Returns whether `limit` changed the set-point.
    pub(crate) fn sync(&mut self, p: f64, period_us: u32, limit: impl Fn(f64) -> (f64, bool)) -> bool {
        self.from = p;
        self.elapsed_us = 0;
        self.period_us = period_us;
        match self.buffer.pop_front() {
            Some(sp) => {
                self.underflow = false;
                let (to, clamped) = limit(f64::from(sp));
                self.to = to;
                clamped
            }
            None => {
                self.underflow = true;
                self.to = p;
                false
            }
        }
    }

    /// Advances by `dt_us` and returns the demand `(position, velocity)` with `dt` seconds.
    pub(crate) fn advance(&mut self, dt_us: u64) -> (f64, f64) {
        self.elapsed_us = self.elapsed_us.saturating_add(dt_us);
        if self.period_us == 0 || self.elapsed_us >= u64::from(self.period_us) {
            return (self.to, 0.0);
        }
        let period = f64::from(self.period_us) * 1e-6;
        let frac = self.elapsed_us as f64 / f64::from(self.period_us);
        (self.from + (self.to - self.from) * frac, (self.to - self.from) / period)
    }

    /// The end of the current segment, and whether the segment is over.
    pub(crate) fn segment_end(&self) -> (f64, bool) {
        (self.to, self.period_us == 0 || self.elapsed_us >= u64::from(self.period_us))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_between_syncs() {
        let mut ip = Interpolator::new();
        assert!(ip.push(100, 2));
        assert!(ip.push(300, 2));
        assert!(!ip.push(500, 2));
        ip.sync(0.0, 4000, |x| (x, false));
        assert_eq!(ip.advance(1000), (25.0, 25_000.0));
        assert_eq!(ip.advance(3000), (100.0, 0.0));
        ip.sync(100.0, 4000, |x| (x, false));
        assert_eq!(ip.advance(2000), (200.0, 50_000.0));
        ip.sync(200.0, 4000, |x| (x, false));
        assert!(ip.underflow);
        assert_eq!(ip.advance(1000), (200.0, 0.0));
    }
}
