//! [`Mask`]: the binary image every stage shares (silhouettes, segmentations,
//! ground truth).

use crate::error::{ModelError, Result};
use crate::range::{Bounds, RangeError};
use crate::roi::Roi;

/// A binary image: one byte per pixel, 0 or 1, row-major.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mask {
    width: u32,
    height: u32,
    data: Vec<u8>,
}

impl Mask {
    /// An empty mask. Zero width or height is an error.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `image width` or `image height` when
    /// it is outside `[1, MAX_IMAGE_SIDE]`.
    pub fn new(width: u32, height: u32) -> Result<Self> {
        crate::range::check_image_size(width, height)?;
        Ok(Self {
            width,
            height,
            data: vec![0; width as usize * height as usize],
        })
    }

    /// A mask over `data` (row-major, non-zero = set); its length must be `width × height`.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `image width` or `image height` when
    /// it is outside `[1, MAX_IMAGE_SIDE]`;
    /// [`ModelError::ImageSize`] when `data.len()` is not `width × height`.
    pub fn from_raw(width: u32, height: u32, data: Vec<u8>) -> Result<Self> {
        crate::range::check_image_size(width, height)?;
        let expected = width as usize * height as usize;
        if data.len() != expected {
            return Err(ModelError::ImageSize {
                what: "mask buffer",
                width,
                height,
                expected,
                got: data.len(),
            });
        }
        Ok(Self {
            width,
            height,
            data: data.into_iter().map(|v| u8::from(v != 0)).collect(),
        })
    }

    /// Width, px.
    #[must_use]
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height, px.
    #[must_use]
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Pixels, row-major, 0 or 1.
    #[must_use]
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// Whether pixel `(x, y)` is set (false outside the image).
    #[must_use]
    pub fn get(&self, x: u32, y: u32) -> bool {
        x < self.width && y < self.height && self.data[(y * self.width + x) as usize] != 0
    }

    /// Number of set pixels.
    #[must_use]
    pub fn count(&self) -> usize {
        self.data.iter().filter(|&&v| v != 0).count()
    }

    /// The window `roi` of this mask; it must lie inside.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming the axis of `roi` that is empty or
    /// reaches past the mask's edge.
    pub fn crop(&self, roi: Roi) -> Result<Mask> {
        roi.check_within(self.width, self.height)?;
        let Roi {
            x0,
            y0,
            width,
            height,
        } = roi;
        let mut data = Vec::with_capacity(width as usize * height as usize);
        for y in y0..y0 + height {
            let row = (y * self.width + x0) as usize;
            data.extend_from_slice(&self.data[row..row + width as usize]);
        }
        Ok(Mask {
            width,
            height,
            data,
        })
    }

    /// Clears every pixel.
    pub fn clear(&mut self) {
        self.data.fill(0);
    }

    /// Intersection over union with `other` (1 when both are empty). Sizes must match.
    ///
    /// # Errors
    /// [`ModelError::ImageSize`] when `other`'s width or height differs from
    /// this mask's.
    pub fn iou(&self, other: &Mask) -> Result<f64> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(ModelError::ImageSize {
                what: "masks compared",
                width: self.width,
                height: self.height,
                expected: self.data.len(),
                got: other.data.len(),
            });
        }
        let (mut inter, mut union) = (0usize, 0usize);
        for (a, b) in self.data.iter().zip(&other.data) {
            inter += usize::from(*a != 0 && *b != 0);
            union += usize::from(*a != 0 || *b != 0);
        }
        Ok(if union == 0 {
            1.0
        } else {
            inter as f64 / union as f64
        })
    }

    /// Makes this a clear `width × height` mask, keeping the allocation where it
    /// is large enough (for loops that refill one mask frame after frame).
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `image width` or `image height` when
    /// it is outside `[1, MAX_IMAGE_SIDE]`; the mask is then left unchanged.
    pub fn reshape(&mut self, width: u32, height: u32) -> Result<()> {
        crate::range::check_image_size(width, height)?;
        self.width = width;
        self.height = height;
        self.data.clear();
        self.data.resize(width as usize * height as usize, 0);
        Ok(())
    }

    /// Writes row `y` from `row` (non-zero = set); `row` must be one row long.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `mask row` when `y` is not below the
    /// height; [`ModelError::ImageSize`] when `row.len()` is not the width.
    /// Nothing is written then.
    pub fn set_row(&mut self, y: u32, row: &[u8]) -> Result<()> {
        if y >= self.height {
            return Err(RangeError {
                name: "mask row",
                value: f64::from(y),
                bounds: Bounds::closed_open(0.0, f64::from(self.height)),
            }
            .into());
        }
        if row.len() != self.width as usize {
            return Err(ModelError::ImageSize {
                what: "mask row",
                width: self.width,
                height: self.height,
                expected: self.width as usize,
                got: row.len(),
            });
        }
        let start = y as usize * self.width as usize;
        for (d, &v) in self.data[start..start + row.len()].iter_mut().zip(row) {
            *d = u8::from(v != 0);
        }
        Ok(())
    }

    /// This mask resampled to `width × height` by area vote: an output pixel
    /// is set where at least half of the pixels whose centres fall in it are
    /// (e.g. a region of interest's mask down to IBJAE's 48×48). An output
    /// pixel no source centre falls in (upsampling) is not set.
    ///
    /// # Errors
    /// [`ModelError::OutOfRange`] naming `image width` or `image height` when
    /// the output size is outside `[1, MAX_IMAGE_SIDE]`.
    pub fn vote(&self, width: u32, height: u32) -> Result<Mask> {
        crate::range::check_image_size(width, height)?;
        let (w, h) = (self.width as usize, self.height as usize);
        let (ow, oh) = (width as usize, height as usize);
        let (mut set, mut all) = (vec![0u32; ow * oh], vec![0u32; ow * oh]);
        for (y, row) in self.data.chunks_exact(w).enumerate() {
            let base = (y * oh / h) * ow;
            for (x, &v) in row.iter().enumerate() {
                let c = base + x * ow / w;
                all[c] += 1;
                set[c] += u32::from(v);
            }
        }
        let data = set
            .iter()
            .zip(&all)
            .map(|(&s, &a)| u8::from(a > 0 && 2 * s >= a))
            .collect();
        Ok(Mask {
            width,
            height,
            data,
        })
    }

    /// Sets pixel `i` of the row-major buffer.
    pub(crate) fn set_index(&mut self, i: usize) {
        self.data[i] = 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vote_sets_cells_at_least_half_covered() {
        // 4×4 → 2×2: top-left 2 of 4 set (half: set), top-right 1 of 4 (not),
        // bottom-left all four, bottom-right none
        let m = Mask::from_raw(4, 4, vec![1, 1, 1, 0, 0, 0, 0, 0, 1, 1, 0, 0, 1, 1, 0, 0]).unwrap();
        assert_eq!(m.vote(2, 2).unwrap().data(), &[1, 0, 1, 0]);
        // the same size gives the same mask; a bad size names the axis
        assert_eq!(m.vote(4, 4).unwrap(), m);
        assert!(matches!(m.vote(0, 2), Err(ModelError::OutOfRange(e)) if e.name == "image width"));
    }
}
