//! Ranges of valid values, the error that says a value left one, and the
//! one check of image sizes.
//!
//! Every crate of the workspace checks its parameters and inputs with
//! [`Bounds::check`], so an out-of-range value is reported the same way
//! everywhere: as a [`RangeError`] that carries the quantity's name, the value
//! and the numeric bounds. The error is `Copy` and building it allocates
//! nothing, so a controller can reject a bad input inside its loop.

use std::fmt;

use serde::Serialize;
use thiserror::Error;

/// An interval of valid values; each end open or closed, either end possibly infinite.
///
/// ```
/// use kflex_model::Bounds;
/// let b = Bounds::closed(0.0, 2.0);
/// assert_eq!(b.check("friction_coefficient", 0.3), Ok(0.3));
/// let err = b.check("friction_coefficient", 2.5).unwrap_err();
/// assert_eq!((err.value, err.bounds.max), (2.5, 2.0));
/// assert_eq!(
///     err.to_string(),
///     "friction_coefficient = 2.5 is out of range: must be in [0, 2]"
/// );
/// ```
/// Serialised (for logs) as its four fields; an infinite end is `null` in JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Bounds {
    /// Lower end (may be `-inf`).
    pub min: f64,
    /// Upper end (may be `inf`).
    pub max: f64,
    /// Whether `min` itself is valid.
    pub min_inclusive: bool,
    /// Whether `max` itself is valid.
    pub max_inclusive: bool,
}

impl Bounds {
    /// `[min, max]`.
    #[must_use]
    pub const fn closed(min: f64, max: f64) -> Self {
        Self {
            min,
            max,
            min_inclusive: true,
            max_inclusive: true,
        }
    }

    /// `(min, max)`; use infinities for one-sided ranges, e.g. `(0, inf)`.
    #[must_use]
    pub const fn open(min: f64, max: f64) -> Self {
        Self {
            min,
            max,
            min_inclusive: false,
            max_inclusive: false,
        }
    }

    /// `[min, max)`.
    #[must_use]
    pub const fn closed_open(min: f64, max: f64) -> Self {
        Self {
            min,
            max,
            min_inclusive: true,
            max_inclusive: false,
        }
    }

    /// `(min, max]`.
    #[must_use]
    pub const fn open_closed(min: f64, max: f64) -> Self {
        Self {
            min,
            max,
            min_inclusive: false,
            max_inclusive: true,
        }
    }

    /// Whether `value` lies in the range. NaN never does; an infinite value
    /// never does either, even where an end is infinite.
    #[must_use]
    pub fn contains(&self, value: f64) -> bool {
        let above = if self.min_inclusive {
            value >= self.min
        } else {
            value > self.min
        };
        let below = if self.max_inclusive {
            value <= self.max
        } else {
            value < self.max
        };
        value.is_finite() && above && below
    }

    /// `value` if it lies in the range.
    ///
    /// # Errors
    /// [`RangeError`] naming `name`, carrying `value` and these bounds, when
    /// `value` is outside the range, NaN or infinite.
    pub fn check(self, name: &'static str, value: f64) -> Result<f64, RangeError> {
        if self.contains(value) {
            Ok(value)
        } else {
            Err(RangeError {
                name,
                value,
                bounds: self,
            })
        }
    }

    /// `value` held inside the range: the nearest end where it lies beyond
    /// one (just inside an open end), else itself (NaN stays NaN).
    #[must_use]
    pub fn hold(&self, value: f64) -> f64 {
        let lo = if self.min_inclusive {
            self.min
        } else {
            self.min.next_up()
        };
        let hi = if self.max_inclusive {
            self.max
        } else {
            self.max.next_down()
        };
        if value < lo {
            lo
        } else if value > hi {
            hi
        } else {
            value
        }
    }
}

impl fmt::Display for Bounds {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let open = if self.min_inclusive { '[' } else { '(' };
        let close = if self.max_inclusive { ']' } else { ')' };
        write!(f, "{open}{}, {}{close}", Num(self.min), Num(self.max))
    }
}

/// A value outside its valid range. `Copy`; building it allocates nothing.
/// Serialised (for logs) as `name`, `value` and `bounds`.
#[derive(Debug, Clone, Copy, PartialEq, Error, Serialize)]
#[error("{name} = {} is out of range: must be in {bounds}", Num(*.value))]
pub struct RangeError {
    /// The quantity, as its field or argument is named (unit in the name where it has one).
    pub name: &'static str,
    /// The value that was given.
    pub value: f64,
    /// Where it had to be.
    pub bounds: Bounds,
}

/// Formats a number for a message: plain decimal for ordinary magnitudes,
/// scientific notation for huge and tiny ones (so `f64::MAX` is `1.7976931348623157e308`,
/// not 309 digits).
///
/// ```
/// assert_eq!(kflex_model::Num(1e308).to_string(), "1e308");
/// assert_eq!(kflex_model::Num(12.5).to_string(), "12.5");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        let a = v.abs();
        if v.is_finite() && a != 0.0 && !(1e-6..1e15).contains(&a) {
            write!(f, "{v:e}")
        } else {
            write!(f, "{v}")
        }
    }
}

/// Largest image side, px: above any endoscope's sensor (a 4K one is 3840 px wide).
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// Checks an image size: each side in `[1, MAX_IMAGE_SIDE]` px.
pub(crate) fn check_image_size(width: u32, height: u32) -> Result<(), RangeError> {
    let side = Bounds::closed(1.0, f64::from(MAX_IMAGE_SIDE));
    side.check("image width", f64::from(width))?;
    side.check("image height", f64::from(height))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_are_respected() {
        let c = Bounds::closed(0.0, 1.0);
        assert!(c.contains(0.0) && c.contains(1.0) && !c.contains(1.0 + 1e-12));
        let o = Bounds::open(0.0, 1.0);
        assert!(!o.contains(0.0) && !o.contains(1.0) && o.contains(0.5));
        assert!(Bounds::closed_open(0.0, 1.0).contains(0.0));
        assert!(!Bounds::closed_open(0.0, 1.0).contains(1.0));
        assert!(!Bounds::open_closed(0.0, 1.0).contains(0.0));
        assert!(Bounds::open_closed(0.0, 1.0).contains(1.0));
    }

    #[test]
    fn a_held_value_lies_in_the_range() {
        let o = Bounds::open(0.0, 1e6);
        for v in [-3.0, 0.0, 0.5, 1e6, 2e6] {
            assert!(o.contains(o.hold(v)), "{v}");
        }
        assert_eq!(o.hold(2e6), 1e6_f64.next_down());
        assert_eq!(o.hold(0.5), 0.5);
        let c = Bounds::closed(-1.0, 1.0);
        assert_eq!((c.hold(-1.2), c.hold(1.0), c.hold(0.3)), (-1.0, 1.0, 0.3));
        assert!(c.hold(f64::NAN).is_nan());
    }

    #[test]
    fn non_finite_values_are_refused_even_by_infinite_ranges() {
        let all = Bounds::open(f64::NEG_INFINITY, f64::INFINITY);
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let err = all.check("x", v).unwrap_err();
            assert_eq!(err.name, "x");
            assert!(err.value.is_nan() || err.value == v);
        }
        assert_eq!(all.check("x", -1e300), Ok(-1e300));
    }

    #[test]
    fn messages_read_as_before_and_stay_short() {
        let err = Bounds::open(0.0, f64::INFINITY)
            .check("pretension_n", -1.0)
            .unwrap_err();
        assert_eq!(
            err.to_string(),
            "pretension_n = -1 is out of range: must be in (0, inf)"
        );
        let err = Bounds::closed(0.0, f64::MAX)
            .check("half_width", -1e308)
            .unwrap_err();
        let msg = err.to_string();
        assert_eq!(
            msg,
            "half_width = -1e308 is out of range: must be in [0, 1.7976931348623157e308]"
        );
        assert_eq!(Num(0.25).to_string(), "0.25");
        assert_eq!(Num(1e-9).to_string(), "1e-9");
        assert_eq!(Num(f64::NAN).to_string(), "NaN");
    }
}
