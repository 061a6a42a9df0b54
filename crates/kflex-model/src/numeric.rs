//! Small numerical tools shared by the model.

/// Root of a decreasing function on `[lo, hi]`: Newton steps from `guess`,
/// safeguarded by bisection (every evaluation narrows the bracket, so Newton
/// cannot cycle), to a bracket narrower than `tol`. `f` returns the value and
/// its slope (an estimate is enough). If `f` stays positive up to `hi` the
/// answer is `hi`; if it is negative from `lo`, `lo`: the bounds act as stops.
pub fn root_decreasing(
    f: impl Fn(f64) -> (f64, f64),
    lo: f64,
    hi: f64,
    guess: f64,
    tol: f64,
) -> f64 {
    let (lo0, hi0) = (lo, hi);
    let (mut lo, mut hi) = (lo, hi);
    let mut x = if guess.is_finite() {
        guess.clamp(lo, hi)
    } else {
        0.5 * (lo + hi)
    };
    for _ in 0..200 {
        let (v, slope) = f(x);
        if v == 0.0 {
            return x;
        }
        if v > 0.0 {
            lo = x;
        } else {
            hi = x;
        }
        if hi - lo <= tol {
            break;
        }
        let newton = x - v / slope;
        let next = if slope < 0.0 && newton > lo && newton < hi {
            newton
        } else {
            0.5 * (lo + hi)
        };
        if (next - x).abs() <= 0.25 * tol {
            return next;
        }
        x = next;
    }
    // at a stop, say so exactly
    if hi <= lo0 + tol && f(lo0).0 <= 0.0 {
        return lo0;
    }
    if lo >= hi0 - tol && f(hi0).0 >= 0.0 {
        return hi0;
    }
    0.5 * (lo + hi)
}

#[cfg(test)]
mod tests {
    use super::*;

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
    fn survives_a_newton_cycle_and_bad_slopes() {
        // piecewise-linear with a kink where plain Newton with a stale slope cycles
        let f = |x: f64| {
            if x < 1.0 {
                (1.0 - 0.01 * x, -1.0)
            } else {
                (1.0 - 0.01 - 5.0 * (x - 1.0), 0.0)
            }
        };
        let r = root_decreasing(f, -10.0, 10.0, 0.0, 1e-13);
        assert!((r - (1.0 + 0.99 / 5.0)).abs() < 1e-11, "{r}");
    }
}
