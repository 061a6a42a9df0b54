//! Resampling the region's mask to the `out × out` image IBJAE consumes, by
//! area vote on the grid of 2×2 cells and the pixels the boundary's
//! refinement changed.

use kflex_model::Mask;

use super::Scratch;
use super::refine::changed;
use crate::error::Result;

/// The area vote (an output cell is set where at least half the pixels it
/// covers are) from the cells (`cols` a row, each the value of its up to
/// 2×2 pixels of the `rw × rh` region) with the pixels of `changes`
/// (index in the region, new value; sorted by index, each differing from
/// its cell) into `out`.
pub(super) fn resample_cells(
    s: &mut Scratch,
    cols: usize,
    rw: usize,
    rh: usize,
    out: &mut Mask,
) -> Result<()> {
    let n = out.width() as usize;
    s.spans.clear();
    s.spans.extend((0..n).map(|ox| vote_span(ox, rw, n)));
    s.row.clear();
    s.row.resize(n, 0);
    s.column.clear();
    s.column.resize(cols, 0);
    s.changed.clear();
    s.changed.resize(n, 0);
    for oy in 0..n {
        let (y0, y1) = vote_span(oy, rh, n);
        // pixels set in each cell column over pixel rows y0..y1
        s.column.fill(0);
        for y in y0..y1 {
            let crow = &s.cells[(y / 2) * cols..][..cols];
            for (c, &v) in s.column.iter_mut().zip(crow) {
                *c += u32::from(v);
            }
        }
        // the changed pixels' difference, per output column whose span
        // holds the pixel (spans are in order; they overlap where the
        // region is narrower than the output)
        s.changed.fill(0);
        let first = s.changes.partition_point(|&c| changed(c).0 < y0 * rw);
        let last = first + s.changes[first..].partition_point(|&c| changed(c).0 < y1 * rw);
        for &c in &s.changes[first..last] {
            // each change differs from its cell: set adds a pixel, clear removes one
            let (i, v) = changed(c);
            let x = i % rw;
            let from = s.spans.partition_point(|&(_, x1)| x1 <= x);
            for (d, _) in s.changed[from..]
                .iter_mut()
                .zip(&s.spans[from..])
                .take_while(|(_, span)| span.0 <= x)
            {
                *d += if v != 0 { 1 } else { -1 };
            }
        }
        for ((r, &(x0, x1)), &d) in s.row.iter_mut().zip(&s.spans).zip(&s.changed) {
            let cells: u32 = (x0..x1).map(|x| s.column[x / 2]).sum();
            let set = i64::from(cells) + i64::from(d);
            *r = u8::from(2 * set >= ((y1 - y0) * (x1 - x0)) as i64);
        }
        out.set_row(oy as u32, &s.row)?;
    }
    Ok(())
}

/// The pixels `[lo, hi)` of `len` that output cell `i` of `n` covers in the area
/// vote (at least one).
fn vote_span(i: usize, len: usize, n: usize) -> (usize, usize) {
    let lo = i * len / n;
    (lo, ((i + 1) * len / n).max(lo + 1).min(len))
}

/// Area vote over a pixel mask: output cell set where at least half of the
/// pixels it covers are. The reference for [`resample_cells`].
#[cfg(test)]
fn resample(mask: &[u8], w: usize, h: usize, out: usize) -> Vec<u8> {
    let xs: Vec<(usize, usize)> = (0..out).map(|ox| vote_span(ox, w, out)).collect();
    let mut res = vec![0u8; out * out];
    let mut column = vec![0u32; w];
    for (oy, res_row) in res.chunks_exact_mut(out).enumerate() {
        let (y0, y1) = vote_span(oy, h, out);
        column.fill(0);
        for row in mask[y0 * w..y1 * w].chunks_exact(w) {
            for (c, &v) in column.iter_mut().zip(row) {
                *c += u32::from(v != 0);
            }
        }
        for (r, &(x0, x1)) in res_row.iter_mut().zip(&xs) {
            let set: u32 = column[x0..x1].iter().sum();
            *r = u8::from(2 * set as usize >= (y1 - y0) * (x1 - x0));
        }
    }
    res
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The area vote from the cells and the changed pixels equals the one
    /// from the pixel mask.
    #[test]
    fn resampling_cells_equals_resampling_pixels() {
        for (rw, rh, n) in [
            (1usize, 1usize, 48usize),
            (7, 5, 3),
            (220, 220, 48),
            (101, 37, 48),
            (30, 90, 7),
        ] {
            let (cols, rows) = (rw.div_ceil(2), rh.div_ceil(2));
            let mut s = Scratch {
                cells: (0..cols * rows)
                    .map(|i| u8::from(i % 7 < 3 || i % 5 == 0))
                    .collect(),
                ..Scratch::default()
            };
            let mut pixels: Vec<u8> = (0..rw * rh)
                .map(|i| s.cells[(i / rw / 2) * cols + (i % rw) / 2])
                .collect();
            // and some pixels changed from their cells' value
            let flips: Vec<usize> = (0..rw * rh).filter(|i| i % 11 == 3).collect();
            s.changes = flips
                .iter()
                .map(|&i| i as u32 | (u32::from(1 - pixels[i]) << 31))
                .collect();
            for &i in &flips {
                pixels[i] = 1 - pixels[i];
            }
            let mut out = Mask::new(n as u32, n as u32).unwrap();
            resample_cells(&mut s, cols, rw, rh, &mut out).unwrap();
            assert_eq!(out.data(), resample(&pixels, rw, rh, n), "{rw}×{rh} → {n}");
        }
    }
}
