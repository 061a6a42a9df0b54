//! [`Roi`]: the region of interest of a frame, shared by the camera simulator
//! (which renders silhouettes of it) and the segmentation (which reads it).
//! The working region is derived from the camera and the instrument, not
//! typed in: see [`Roi::paper`] (in `working.rs`).

use serde::{Deserialize, Serialize};

use crate::camera::Intrinsics;
use crate::error::Result;
use crate::range::Bounds;

/// A region of interest in pixels: `[x0, x0 + width) × [y0, y0 + height)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Roi {
    /// Left column, px.
    pub x0: u32,
    /// Top row, px.
    pub y0: u32,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
}

impl Roi {
    /// The whole of a `width × height` image.
    #[must_use]
    pub const fn whole(width: u32, height: u32) -> Roi {
        Roi {
            x0: 0,
            y0: 0,
            width,
            height,
        }
    }

    /// Whether `inner` lies inside this region.
    #[must_use]
    pub fn holds(&self, inner: &Roi) -> bool {
        self.x0 <= inner.x0
            && self.y0 <= inner.y0
            && u64::from(self.x0) + u64::from(self.width)
                >= u64::from(inner.x0) + u64::from(inner.width)
            && u64::from(self.y0) + u64::from(self.height)
                >= u64::from(inner.y0) + u64::from(inner.height)
    }

    /// Checks that the region is not empty and lies inside a `width × height` image.
    ///
    /// # Errors
    /// [`crate::ModelError::OutOfRange`] naming the axis that fails: `roi.width` or
    /// `roi.height` when empty, `roi.x0 + roi.width` or `roi.y0 + roi.height`
    /// past the image's edge (the bounds are the image's).
    pub fn check_within(&self, width: u32, height: u32) -> Result<()> {
        Bounds::closed(1.0, f64::from(u32::MAX)).check("roi.width", f64::from(self.width))?;
        Bounds::closed(1.0, f64::from(u32::MAX)).check("roi.height", f64::from(self.height))?;
        let right = u64::from(self.x0) + u64::from(self.width);
        let bottom = u64::from(self.y0) + u64::from(self.height);
        Bounds::closed(1.0, f64::from(width)).check("roi.x0 + roi.width", right as f64)?;
        Bounds::closed(1.0, f64::from(height)).check("roi.y0 + roi.height", bottom as f64)?;
        Ok(())
    }

    /// The smallest region holding both.
    #[must_use]
    pub fn union(&self, other: &Roi) -> Roi {
        let x0 = self.x0.min(other.x0);
        let y0 = self.y0.min(other.y0);
        let right = (u64::from(self.x0) + u64::from(self.width))
            .max(u64::from(other.x0) + u64::from(other.width));
        let bottom = (u64::from(self.y0) + u64::from(self.height))
            .max(u64::from(other.y0) + u64::from(other.height));
        Roi {
            x0,
            y0,
            width: u32::try_from(right - u64::from(x0)).unwrap_or(u32::MAX),
            height: u32::try_from(bottom - u64::from(y0)).unwrap_or(u32::MAX),
        }
    }

    /// Number of pixels.
    #[must_use]
    pub fn area(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height)
    }

    /// The intrinsics of the camera that sees this region of an image taken
    /// with `full`, resampled to `out_w × out_h` ([`Intrinsics::region`] of
    /// a pixel-aligned region; e.g. IBJAE's 48×48).
    ///
    /// # Errors
    /// As [`Intrinsics::region`].
    pub fn intrinsics(&self, full: &Intrinsics, out_w: u32, out_h: u32) -> Result<Intrinsics> {
        full.region(
            f64::from(self.x0),
            f64::from(self.y0),
            f64::from(self.width),
            f64::from(self.height),
            out_w,
            out_h,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::ModelError;

    /// The range error of `roi` checked in a 640×480 image.
    fn failure(x0: u32, y0: u32, width: u32, height: u32) -> crate::range::RangeError {
        match (Roi {
            x0,
            y0,
            width,
            height,
        })
        .check_within(640, 480)
        {
            Err(ModelError::OutOfRange(e)) => e,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_region_holds_what_lies_inside_it() {
        let whole = Roi::whole(640, 480);
        assert!(whole.check_within(640, 480).is_ok());
        let inner = Roi {
            x0: 10,
            y0: 20,
            width: 630,
            height: 460,
        };
        assert!(whole.holds(&inner) && whole.holds(&whole) && !inner.holds(&whole));
        let past = Roi {
            width: 631,
            ..inner
        };
        assert!(!whole.holds(&past));
        // no overflow at the far end of u32
        let far = Roi {
            x0: u32::MAX - 1,
            y0: 0,
            width: 5,
            height: 1,
        };
        assert!(!whole.holds(&far) && !far.holds(&whole));
    }

    #[test]
    fn regions_outside_the_image_name_the_axis() {
        let e = failure(600, 10, 50, 50);
        assert_eq!(
            (e.name, e.value, e.bounds.max),
            ("roi.x0 + roi.width", 650.0, 640.0)
        );
        let e = failure(0, 470, 50, 50);
        assert_eq!(
            (e.name, e.value, e.bounds.max),
            ("roi.y0 + roi.height", 520.0, 480.0)
        );
        assert_eq!(failure(0, 0, 0, 5).name, "roi.width");
        assert_eq!(failure(0, 0, 5, 0).name, "roi.height");
        // no overflow past u32::MAX: the sum is taken in u64
        let e = failure(u32::MAX, 0, 2, 2);
        assert_eq!(e.name, "roi.x0 + roi.width");
        assert!(e.value > f64::from(u32::MAX));
        assert!(
            Roi {
                x0: 0,
                y0: 0,
                width: 640,
                height: 480
            }
            .check_within(640, 480)
            .is_ok()
        );
    }

    #[test]
    fn the_union_holds_both_and_nothing_more() {
        let a = Roi {
            x0: 10,
            y0: 20,
            width: 30,
            height: 40,
        };
        let b = Roi {
            x0: 25,
            y0: 5,
            width: 100,
            height: 10,
        };
        let u = a.union(&b);
        assert!(u.holds(&a) && u.holds(&b));
        assert_eq!(
            u,
            Roi {
                x0: 10,
                y0: 5,
                width: 115,
                height: 55
            }
        );
        assert_eq!(a.union(&a), a);
        assert_eq!(b.union(&a), u);
        // past u32::MAX it saturates rather than wrapping
        let far = Roi {
            x0: u32::MAX - 1,
            y0: 0,
            width: 10,
            height: 1,
        };
        assert_eq!(Roi::whole(1, 1).union(&far).width, u32::MAX);
    }
}
