//! Trapezoidal velocity profiles, planned in closed form.
//!
//! A [`Plan`] is a short list of constant-acceleration segments starting from a known state
//! `(p0, v0)`, followed by an endless cruise at the final velocity. It is evaluated at a time
//! since its start, so the demand does not depend on the step size the caller uses, and a
//! position move ends *exactly* on its target (the last segment is snapped, and the final
//! approach is clamped so rounding can never carry the demand past the target).
//!
//! Rules every plan follows:
//! * the speed |v| never exceeds the profile velocity, except when the plan starts faster, in
//!   which case its first segment decelerates to it;
//! * speed grows at the acceleration and shrinks at the deceleration, never faster;
//! * a position move that cannot stop in time (moving away from the target, or too fast for the
//!   distance left) first decelerates to standstill and then comes back.

/// One constant-acceleration piece of a plan.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Segment {
    /// Duration in seconds.
    dur: f64,
    /// Acceleration in position units/s² (signed).
    acc: f64,
}

/// Most segments a plan needs: decelerate to zero, accelerate, cruise, decelerate (plus a spare).
const MAX_SEGMENTS: usize = 5;

/// A planned trajectory in position units and seconds.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Plan {
    p0: f64,
    v0: f64,
    segs: [Segment; MAX_SEGMENTS],
    n: usize,
    total: f64,
    end_p: f64,
    end_v: f64,
    /// For position moves: the target, and from which time on the demand must not pass it
    /// (in direction `clamp_dir`).
    target: Option<f64>,
    clamp_from: f64,
    clamp_dir: f64,
}

impl Plan {
    /// Standing still at `p`.
    pub(crate) fn hold(p: f64) -> Plan {
        Plan {
            p0: p,
            v0: 0.0,
            segs: [Segment::default(); MAX_SEGMENTS],
            n: 0,
            total: 0.0,
            end_p: p,
            end_v: 0.0,
            target: None,
            clamp_from: 0.0,
            clamp_dir: 0.0,
        }
    }

    fn start(p0: f64, v0: f64) -> Plan {
        let mut plan = Plan::hold(p0);
        plan.v0 = v0;
        plan.end_v = v0;
        plan
    }

    fn push(&mut self, dur: f64, acc: f64) {
        if dur.is_nan() || dur <= 0.0 || !dur.is_finite() || self.n == MAX_SEGMENTS {
            return;
        }
        let v = self.end_v;
        self.segs[self.n] = Segment { dur, acc };
        self.n += 1;
        self.total += dur;
        self.end_p += v * dur + 0.5 * acc * dur * dur;
        self.end_v = v + acc * dur;
    }

    /// Ramps the velocity from `v0` to `vt` and then cruises at `vt` forever.
    ///
    /// Speed grows at `acc` and shrinks at `dec`; a sign change first decelerates to zero.
    /// `None` when a rate that is needed is zero (or not finite): the velocity cannot change.
    pub(crate) fn velocity(p0: f64, v0: f64, vt: f64, acc: f64, dec: f64) -> Option<Plan> {
        let mut plan = Plan::start(p0, v0);
        if v0 == vt {
            return Some(plan);
        }
        let ok = |r: f64| r > 0.0 && r.is_finite();
        if v0 != 0.0 && (vt == 0.0 || v0.signum() != vt.signum()) {
            // Slow down to standstill first.
            if !ok(dec) {
                return None;
            }
            plan.push(v0.abs() / dec, -v0.signum() * dec);
            plan.end_v = 0.0;
            if vt != 0.0 {
                if !ok(acc) {
                    return None;
                }
                plan.push(vt.abs() / acc, vt.signum() * acc);
            }
        } else if vt.abs() > v0.abs() {
            if !ok(acc) {
                return None;
            }
            plan.push((vt.abs() - v0.abs()) / acc, vt.signum() * acc);
        } else {
            if !ok(dec) {
                return None;
            }
            plan.push((v0.abs() - vt.abs()) / dec, -v0.signum() * dec);
        }
        plan.end_v = vt;
        Some(plan)
    }

    /// A point-to-point move from `(p0, v0)` to `target`, arriving with speed `vf` (0 for a stop,
    /// more to blend into a following move in the same direction).
    ///
    /// `vmax`, `acc` and `dec` must be positive and finite, else `None`. `vf` is limited to
    /// `vmax`. When the move cannot reach `vf` before the target (too short to accelerate, or to
    /// slow down when `vf > 0`) it arrives with the speed it can reach instead; with `vf = 0` it
    /// always stops exactly on the target.
    pub(crate) fn position(p0: f64, v0: f64, target: f64, vmax: f64, acc: f64, dec: f64, vf: f64) -> Option<Plan> {
        let ok = |r: f64| r > 0.0 && r.is_finite();
        if !(ok(vmax) && ok(acc) && ok(dec)) {
            return if p0 == target && v0 == 0.0 { Some(Plan::hold(target)) } else { None };
        }
        let vf = if vf.is_finite() { vf.clamp(0.0, vmax) } else { 0.0 };
        let mut plan = Plan::start(p0, v0);
        // At most two passes: the first may only decelerate to standstill (moving away, or
        // unable to stop before the target); the second is the forward move.
        for _ in 0..3 {
            let d = target - plan.end_p;
            let v = plan.end_v;
            if d == 0.0 && v == 0.0 && vf == 0.0 {
                break;
            }
            let s = if d > 0.0 {
                1.0
            } else if d < 0.0 {
                -1.0
            } else if v != 0.0 {
                // On the target but moving: stop, then come back.
                -v.signum()
            } else {
                // On the target, standing, asked to arrive moving: nothing to do.
                break;
            };
            let u = s * v; // speed towards the target
            let dist = d.abs();
            let stop_dist = u * u / (2.0 * dec);
            if u < 0.0 || (vf == 0.0 && stop_dist > dist) {
                // Moving away, or too fast to stop on the target: decelerate to standstill.
                plan.push(v.abs() / dec, -v.signum() * dec);
                plan.end_v = 0.0;
                continue;
            }
            plan.clamp_from = plan.total;
            plan.clamp_dir = s;
            plan.forward(s, u, dist, vmax, acc, dec, vf);
            break;
        }
        plan.end_p = target;
        if plan.end_v.abs() < 1e-9 * vmax {
            plan.end_v = 0.0;
        }
        plan.target = Some(target);
        Some(plan)
    }

    /// The forward part of a move: speed `u >= 0` towards a target `dist` away in direction `s`.
    #[allow(clippy::too_many_arguments)]
    fn forward(&mut self, s: f64, u: f64, dist: f64, vmax: f64, acc: f64, dec: f64, vf: f64) {
        if u > vf && (u * u - vf * vf) / (2.0 * dec) > dist {
            // Blending and too fast to reach vf: slow down as much as the distance allows.
            let v_end = (u * u - 2.0 * dec * dist).max(0.0).sqrt();
            self.push((u - v_end) / dec, -s * dec);
            self.end_v = s * v_end;
            return;
        }
        if u > vmax {
            let t1 = (u - vmax) / dec;
            let d1 = (u * u - vmax * vmax) / (2.0 * dec);
            let d3 = (vmax * vmax - vf * vf) / (2.0 * dec);
            let dc = (dist - d1 - d3).max(0.0);
            self.push(t1, -s * dec);
            self.end_v = s * vmax;
            self.push(dc / vmax, 0.0);
            self.push((vmax - vf) / dec, -s * dec);
            self.end_v = s * vf;
            return;
        }
        // Peak speed of a triangle: (vp² - u²)/(2 acc) + (vp² - vf²)/(2 dec) = dist.
        let vp2 = (2.0 * acc * dec * dist + dec * u * u + acc * vf * vf) / (acc + dec);
        let vp = vp2.max(0.0).sqrt();
        if vp < vf {
            // Too short to reach vf: accelerate all the way.
            let v_end = (u * u + 2.0 * acc * dist).sqrt();
            self.push((v_end - u) / acc, s * acc);
            self.end_v = s * v_end;
            return;
        }
        if vp > vmax {
            let t1 = (vmax - u) / acc;
            let d1 = (vmax * vmax - u * u) / (2.0 * acc);
            let d3 = (vmax * vmax - vf * vf) / (2.0 * dec);
            let dc = (dist - d1 - d3).max(0.0);
            self.push(t1, s * acc);
            self.end_v = s * vmax;
            self.push(dc / vmax, 0.0);
            self.push((vmax - vf) / dec, -s * dec);
        } else {
            let vp = vp.max(u);
            self.push((vp - u) / acc, s * acc);
            self.end_v = s * vp;
            self.push((vp - vf) / dec, -s * dec);
        }
        self.end_v = s * vf;
    }

    /// Position and velocity `t` seconds after the start of the plan.
    pub(crate) fn eval(&self, t: f64) -> (f64, f64) {
        if t >= self.total {
            let dt = t - self.total;
            return (self.end_p + self.end_v * dt, self.end_v);
        }
        let (mut p, mut v, mut t0) = (self.p0, self.v0, 0.0);
        for seg in &self.segs[..self.n] {
            let tau = (t - t0).min(seg.dur);
            if tau <= 0.0 {
                break;
            }
            p += v * tau + 0.5 * seg.acc * tau * tau;
            v += seg.acc * tau;
            t0 += seg.dur;
            if t0 > t {
                break;
            }
        }
        if let Some(target) = self.target
            && t >= self.clamp_from
            && self.clamp_dir != 0.0
            && (target - p) * self.clamp_dir < 0.0
        {
            p = target;
        }
        (p, v)
    }

    /// Duration of the segments (after it the plan cruises at its final velocity).
    pub(crate) fn duration(&self) -> f64 {
        self.total
    }

    /// True once `t` seconds have passed and the final velocity is zero: the demand stands still.
    pub(crate) fn settled(&self, t: f64) -> bool {
        t >= self.total && self.end_v == 0.0
    }

    /// Where the plan comes to rest, if it does.
    pub(crate) fn final_position(&self) -> Option<f64> {
        (self.end_v == 0.0).then_some(self.end_p)
    }

    /// The velocity the plan ends with.
    pub(crate) fn end_velocity(&self) -> f64 {
        self.end_v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(plan: &Plan, dt: f64) -> Vec<(f64, f64)> {
        let n = (plan.duration() / dt).ceil() as usize + 2;
        (0..=n).map(|i| plan.eval(i as f64 * dt)).collect()
    }

    #[test]
    fn trapezoid_matches_closed_form() {
        // 720 units at vmax 360, acc = dec = 360: 1 s up, 1 s cruise, 1 s down.
        let plan = Plan::position(0.0, 0.0, 720.0, 360.0, 360.0, 360.0, 0.0).unwrap();
        assert!((plan.duration() - 3.0).abs() < 1e-12);
        assert_eq!(plan.eval(3.0), (720.0, 0.0));
        let (p, v) = plan.eval(1.0);
        assert!((p - 180.0).abs() < 1e-9 && (v - 360.0).abs() < 1e-9);
        let (p, _) = plan.eval(1.5);
        assert!((p - 360.0).abs() < 1e-9);
    }

    #[test]
    fn triangle_for_short_moves() {
        let plan = Plan::position(0.0, 0.0, 100.0, 1000.0, 100.0, 100.0, 0.0).unwrap();
        // vp = sqrt(acc * dist) = 100, t = 2 s.
        assert!((plan.duration() - 2.0).abs() < 1e-12);
        let peak = sample(&plan, 0.001).iter().map(|s| s.1).fold(0.0, f64::max);
        assert!((peak - 100.0).abs() < 0.2, "peak {peak}");
    }

    #[test]
    fn moving_away_decelerates_then_returns() {
        let plan = Plan::position(0.0, -100.0, 50.0, 200.0, 100.0, 100.0, 0.0).unwrap();
        let samples = sample(&plan, 0.001);
        let min = samples.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
        assert!((min + 50.0).abs() < 0.01, "min {min}");
        assert_eq!(samples.last().unwrap().0, 50.0);
        assert!(samples.iter().all(|s| s.0 <= 50.0));
    }

    #[test]
    fn too_fast_overshoots_then_comes_back_without_passing_target_on_the_way_back() {
        let plan = Plan::position(0.0, 100.0, 10.0, 200.0, 100.0, 100.0, 0.0).unwrap();
        let samples = sample(&plan, 0.001);
        let max = samples.iter().map(|s| s.0).fold(f64::NEG_INFINITY, f64::max);
        assert!((max - 50.0).abs() < 0.01);
        assert_eq!(samples.last().unwrap().0, 10.0);
    }

    #[test]
    fn faster_than_vmax_slows_down_first() {
        let plan = Plan::position(0.0, 300.0, 1000.0, 100.0, 100.0, 100.0, 0.0).unwrap();
        assert_eq!(plan.eval(plan.duration()).0, 1000.0);
        let (_, v) = plan.eval(2.0);
        assert!((v - 100.0).abs() < 1e-9);
    }

    #[test]
    fn blend_arrives_moving() {
        let plan = Plan::position(0.0, 0.0, 1000.0, 100.0, 100.0, 100.0, 100.0).unwrap();
        assert_eq!(plan.end_velocity(), 100.0);
        assert_eq!(plan.eval(plan.duration()).0, 1000.0);
        // Accelerate 1 s (50 units), cruise 950 units.
        assert!((plan.duration() - 10.5).abs() < 1e-9);
    }

    #[test]
    fn velocity_ramp_through_zero() {
        let plan = Plan::velocity(0.0, 100.0, -50.0, 10.0, 20.0).unwrap();
        assert!((plan.duration() - 10.0).abs() < 1e-12); // 5 s down, 5 s up
        assert_eq!(plan.eval(100.0).1, -50.0);
        assert!(Plan::velocity(0.0, 0.0, 10.0, 0.0, 1.0).is_none());
    }

    #[test]
    fn zero_parameters_refuse_to_move() {
        assert!(Plan::position(0.0, 0.0, 10.0, 0.0, 1.0, 1.0, 0.0).is_none());
        assert!(Plan::position(5.0, 0.0, 5.0, 0.0, 0.0, 0.0, 0.0).is_some());
    }
}
