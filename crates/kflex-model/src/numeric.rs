//! Small numerical tools shared by the model.

/// Root of a function that is decreasing on `[lo, hi]` (positive at `lo`,
/// negative at `hi`): Newton steps from `guess`, safeguarded rtsafe-style —
/// a bisection whenever the Newton step leaves the bracket or fails to halve
/// it — until the bracket is narrower than `tol`. `f` returns the value and
/// its slope (an estimate is enough; a poor one costs steps, not accuracy).
/// If `f` stays positive up to `hi` the answer is `hi`; if it is negative from
/// `lo`, `lo`: the bounds act as stops. The answer is always within `tol` of a
/// sign change of `f` (or a stop), never the middle of an unresolved bracket.
/// NaN as soon as `f` gives NaN (it has no answer there to search by).
pub(crate) fn root_decreasing(
    mut f: impl FnMut(f64) -> (f64, f64),
    lo: f64,
    hi: f64,
    guess: f64,
    tol: f64,
) -> f64 {
    let (mut lo, mut hi) = (lo, hi);
    let (lo0, hi0) = (lo, hi);
    let mut x = if guess.is_finite() {
        guess.clamp(lo, hi)
    } else {
        0.5 * (lo + hi)
    };
    let mut width_before = hi - lo;
    // 200 iterations: bisection alone resolves 2^-200 of the range
    for _ in 0..200 {
        let (v, slope) = f(x);
        if v.is_nan() {
            return f64::NAN;
        }
        if v == 0.0 {
            return x;
        }
        if v > 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        let width = hi - lo;
        if width <= tol {
            break;
        }
        let newton = x - v / slope;
        let newton_ok = slope < 0.0 && newton > lo && newton < hi && width <= 0.5 * width_before;
        width_before = width;
        x = if newton_ok { newton } else { 0.5 * (lo + hi) };
    }
    // resolved to tol: report the stop exactly where the root is at it
    if hi <= lo0 + tol {
        let v = f(lo0).0;
        if v.is_nan() {
            return f64::NAN;
        }
        if v <= 0.0 {
            return lo0;
        }
    }
    if lo >= hi0 - tol {
        let v = f(hi0).0;
        if v.is_nan() {
            return f64::NAN;
        }
        if v >= 0.0 {
            return hi0;
        }
    }
    0.5 * (lo + hi)
}

/// The first root of `f` met when walking from `start` in the direction `f`
/// points to (up where `f(start) > 0`, down where it is negative), within
/// `[lo, hi]`: quasi-static path following. Steps of `step` doubling until the
/// sign changes, then [`root_decreasing`] on that bracket. Returns the bound
/// reached if there is no sign change before it, and NaN as soon as `f`
/// gives NaN.
pub(crate) fn follow_root(
    mut f: impl FnMut(f64) -> (f64, f64),
    lo: f64,
    hi: f64,
    start: f64,
    step: f64,
    tol: f64,
) -> f64 {
    let start = if start.is_finite() {
        start.clamp(lo, hi)
    } else {
        0.5 * (lo + hi)
    };
    let (v0, _) = f(start);
    if v0.is_nan() {
        return f64::NAN;
    }
    if v0 == 0.0 {
        return start;
    }
    let dir = v0.signum();
    let (mut near, mut h) = (start, step);
    loop {
        let far = (near + dir * h).clamp(lo, hi);
        let (v, _) = f(far);
        if v.is_nan() {
            return f64::NAN;
        }
        if v.signum() != dir || v == 0.0 {
            let (a, b) = if dir > 0.0 { (near, far) } else { (far, near) };
            return root_decreasing(&mut f, a, b, 0.5 * (a + b), tol);
        }
        if far == lo || far == hi {
            return far;
        }
        near = far;
        h *= 2.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_nan_stops_the_search() {
        // no answer where f has none: NaN, not a root guessed past it
        let f = |x: f64| {
            if x > 0.3 {
                (f64::NAN, f64::NAN)
            } else {
                (0.5 - x, -1.0)
            }
        };
        assert!(root_decreasing(f, 0.0, 1.0, 0.1, 1e-12).is_nan());
        assert!(follow_root(f, -1.0, 1.0, 0.0, 0.01, 1e-12).is_nan());
        assert!(follow_root(|_| (f64::NAN, 0.0), -1.0, 1.0, 0.0, 0.01, 1e-12).is_nan());
        let r = follow_root(f, -1.0, 1.0, -0.5, 0.01, 1e-12);
        assert!(r.is_nan(), "the root at 0.5 lies past the NaN at 0.3: {r}");
        // a NaN that the search never reaches changes nothing
        let g = |x: f64| {
            if x > 0.8 {
                (f64::NAN, 0.0)
            } else {
                (0.5 - x, -1.0)
            }
        };
        let r = follow_root(g, -1.0, 1.0, 0.0, 0.01, 1e-12);
        assert!((r - 0.5).abs() < 1e-11, "{r}");
    }

    #[test]
    fn finds_roots_and_stops() {
        let r = root_decreasing(|x| (2.0 - x * x * x, -3.0 * x * x), 0.0, 3.0, 0.1, 1e-14);
        assert!((r - 2f64.cbrt()).abs() < 1e-12);
        assert_eq!(
            root_decreasing(|x| (10.0 - x, -1.0), 0.0, 3.0, 1.0, 1e-14),
            3.0
        );
        assert_eq!(
            root_decreasing(|x| (-10.0 - x, -1.0), 0.0, 3.0, 1.0, 1e-14),
            0.0
        );
    }

    #[test]
    fn a_too_steep_slope_estimate_still_converges_to_the_root() {
        // the estimate is 10x the true slope: Newton creeps; the safeguard must bisect
        let f = |x: f64| (0.5 - x, -10.0);
        let r = root_decreasing(f, -2.0, 2.0, -1.9, 1e-12);
        assert!((r - 0.5).abs() < 1e-11, "{r}");
    }

    #[test]
    fn survives_a_kink_and_a_zero_slope() {
        let f = |x: f64| {
            if x < 1.0 {
                (1.0 - 0.01 * x, -1.0)
            } else {
                (0.99 - 5.0 * (x - 1.0), 0.0)
            }
        };
        let r = root_decreasing(f, -10.0, 10.0, 0.0, 1e-13);
        assert!((r - (1.0 + 0.99 / 5.0)).abs() < 1e-11, "{r}");
    }

    #[test]
    fn path_following_takes_the_nearest_stable_root() {
        // f = x − x³: roots at −1 and +1 (stable: f decreases through them) and 0 (unstable)
        let f = |x: f64| (x - x * x * x, 1.0 - 3.0 * x * x);
        // from 0.5, f > 0: walk up to the stable root +1, not down to 0
        assert!((follow_root(f, -3.0, 3.0, 0.5, 0.01, 1e-12) - 1.0).abs() < 1e-10);
        // from −0.5, f < 0: walk down to −1
        assert!((follow_root(f, -3.0, 3.0, -0.5, 0.01, 1e-12) + 1.0).abs() < 1e-10);
        // no root before the stop
        assert_eq!(
            follow_root(|x| (5.0 - x, -1.0), -1.0, 2.0, 0.0, 0.01, 1e-12),
            2.0
        );
    }
}
