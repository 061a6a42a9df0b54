//! The boundary to the pixel: the split, merge and threshold decide 2×2
//! cells, so a boundary they draw is off by up to a pixel, and where the
//! optics blur the instrument's edge the cells of the blurred rim go to
//! whichever class their mean colour is nearer (often the steel's: a grey
//! rim over dark lumen is neutral). Here each pixel of the cells along the
//! boundary is decided on its own, against two colours read a few pixels to
//! either side of its cell across the boundary: it takes the class whose
//! colour it is nearer. A straight step edge blurred by a symmetric kernel
//! crosses half way between the two colours at the edge where both are read
//! clear of the blur; where the blur reaches them, they are read
//! symmetrically about the cell's centre, not about the edge, and the half
//! way point may move by a pixel (at the default reach of 4 px, vertical
//! edges at any of five neighbouring columns land on their column under a
//! Gaussian blur of 0.5–2.5 px; under 3 px, three of the five land a column
//! off, where the cells alone are off by up to two). The colours are read
//! beside the cell, so tissue that changes along the instrument (dark lumen
//! on one side, bright mucosa on the other) is no trouble. Where a part is
//! too thin for that (a jaw, or a spike of blurred rim a cell wide that
//! the threshold took for steel: a mix of grey and black is neutral), the
//! samples across it both land in the tissue; such a cell reads its two
//! colours at the nearest cells of each class that lie clear of the
//! boundary instead (until 2026-11-29 it kept the cells' decision).

use super::Scratch;
use super::pyramid::Region2d;

/// Marks in `band` (one byte a cell, `cols × rows`) every cell with a cell
/// of the other class among its eight neighbours: both cells of every pair
/// of neighbours that differ.
fn mark_band(cells: &[u8], cols: usize, rows: usize, band: &mut Vec<u8>, diff: &mut Vec<u8>) {
    band.clear();
    band.resize(cols * rows, 0);
    diff.clear();
    diff.resize(4 * cols, 0);
    let (across, rest) = diff.split_at_mut(cols);
    let (down, rest) = rest.split_at_mut(cols);
    let (down_right, down_left) = rest.split_at_mut(cols);
    // each loop compares whole rows and writes each byte once, so that the
    // compiler vectorises it; a pair's last entry (no right neighbour) stays 0
    for y in 0..rows {
        let here = &cells[y * cols..(y + 1) * cols];
        // across[x]: here[x] against here[x + 1]
        for (o, w) in across.iter_mut().zip(here.windows(2)) {
            *o = w[0] ^ w[1];
        }
        let marks = &mut band[y * cols..(y + 1) * cols];
        marks[0] |= across[0];
        for ((m, &a), &b) in marks[1..]
            .iter_mut()
            .zip(&across[1..])
            .zip(&across[..cols - 1])
        {
            *m |= a | b;
        }
        if y + 1 == rows {
            break;
        }
        let below = &cells[(y + 1) * cols..(y + 2) * cols];
        // down[x]: here[x] against below[x]; down_right[x]: here[x] against
        // below[x + 1]; down_left[x]: here[x + 1] against below[x]
        for ((o, &a), &b) in down.iter_mut().zip(here).zip(below) {
            *o = a ^ b;
        }
        for ((o, &a), &b) in down_right.iter_mut().zip(here).zip(&below[1..]) {
            *o = a ^ b;
        }
        for ((o, &a), &b) in down_left.iter_mut().zip(&here[1..]).zip(below) {
            *o = a ^ b;
        }
        let (top, bottom) = band[y * cols..(y + 2) * cols].split_at_mut(cols);
        // a cell above: its down and down-right pairs, and its down-left
        // pair (down_left[x − 1]); a cell below: its up pair, the down-right
        // pair of the cell above-left (down_right[x − 1]), and down_left[x]
        top[0] |= down[0] | down_right[0];
        bottom[0] |= down[0] | down_left[0];
        for (((t, &d), &dr), &dl) in top[1..]
            .iter_mut()
            .zip(&down[1..])
            .zip(&down_right[1..])
            .zip(&down_left[..cols - 1])
        {
            *t |= d | dr | dl;
        }
        for (((b, &d), &dr), &dl) in bottom[1..]
            .iter_mut()
            .zip(&down[1..])
            .zip(&down_right[..cols - 1])
            .zip(&down_left[1..])
        {
            *b |= d | dr | dl;
        }
    }
}

/// The features (brightness `r + g + b`, redness `2r − g − b`, `g − b`:
/// the split's, a linear map of RGB) summed over the pixels `x0..x1 ×
/// y0..y1` clipped to the region, and how many pixels that is.
#[inline]
fn box_sum(region: &Region2d, [x0, y0, x1, y1]: [isize; 4]) -> ([i64; 3], i64) {
    if x1 - x0 == 4
        && y1 - y0 == 4
        && x0 >= 0
        && y0 >= 0
        && x1 as usize <= region.width
        && y1 as usize <= region.height
    {
        return (features(box4(region, x0 as usize, y0 as usize)), 16);
    }
    clipped_sum(region, [x0, y0, x1, y1])
}

/// [`box_sum`] for any box, pixel by pixel.
fn clipped_sum(region: &Region2d, [x0, y0, x1, y1]: [isize; 4]) -> ([i64; 3], i64) {
    let clip = |v: isize, n: usize| v.clamp(0, n as isize) as usize;
    let (x0, x1) = (clip(x0, region.width), clip(x1, region.width));
    let (y0, y1) = (clip(y0, region.height), clip(y1, region.height));
    let mut sum = [0i64; 3];
    for yy in y0..y1 {
        let start = region.first + yy * region.stride;
        for px in region.rgb[start + 3 * x0..start + 3 * x1].chunks_exact(3) {
            (0..3).for_each(|k| sum[k] += i64::from(px[k]));
        }
    }
    (
        features(sum),
        (x1.saturating_sub(x0) * y1.saturating_sub(y0)) as i64,
    )
}

/// The colour summed over the 4×4 pixels from `(x0, y0)`, which lie in
/// the region: each row's twelve bytes added lane by lane (a lane adds four
/// bytes, at most 1,020: a `u16`), then the lanes folded into the three
/// channels.
#[inline]
fn box4(region: &Region2d, x0: usize, y0: usize) -> [i64; 3] {
    let mut lanes = [0u16; 12];
    for y in y0..y0 + 4 {
        let start = region.first + y * region.stride + 3 * x0;
        for (l, &v) in lanes.iter_mut().zip(&region.rgb[start..start + 12]) {
            *l += u16::from(v);
        }
    }
    std::array::from_fn(|k| (0..4).map(|j| i64::from(lanes[3 * j + k])).sum())
}

/// The features of a colour (or of a sum of colours) `[r, g, b]`.
#[inline]
fn features([r, g, b]: [i64; 3]) -> [i64; 3] {
    [r + g + b, 2 * r - g - b, g - b]
}

/// Sensor noise (σ on the `[0, 1]` scale, per channel) above which a
/// pixel's own colour is read as the mean of its 3×3 pixels: at 0.03 the
/// noise of one pixel's features (√2 σ to √6 σ: 0.04–0.07) is about a third
/// of the least contrast acted on (0.2), and a mean would round the
/// instrument's sharp corners off.
const NOISY: f32 = 0.03;

/// The farthest, in cells, that [`refine`] looks for the nearest cell of a
/// class clear of the boundary (the default reach of 4 px looks 4 cells).
const MAX_INTERIOR_CELLS: usize = 8;

/// A changed pixel: its index in the region (below 2²⁴) and its class in bit 31.
#[inline]
fn change(index: u32, class: u8) -> u32 {
    index | (u32::from(class) << 31)
}

/// The index and class of a [`change`].
#[inline]
pub(super) fn changed(c: u32) -> (usize, u8) {
    ((c & 0x7FFF_FFFF) as usize, (c >> 31) as u8)
}

/// The nearest cell to `(cx, cy)` (Euclidean, within `radius` cells; the
/// first in row order among equals) that is of `class` and has its eight
/// neighbours (those in the grid) of it too: a colour of that class read
/// clear of the boundary.
fn nearest_interior(
    cells: &[u8],
    cols: usize,
    rows: usize,
    cx: usize,
    cy: usize,
    class: u8,
    radius: usize,
) -> Option<(usize, usize)> {
    let mut best: Option<(usize, (usize, usize))> = None;
    for y in cy.saturating_sub(radius)..(cy + radius + 1).min(rows) {
        for x in cx.saturating_sub(radius)..(cx + radius + 1).min(cols) {
            let d2 = x.abs_diff(cx).pow(2) + y.abs_diff(cy).pow(2);
            if best.is_some_and(|(b, _)| d2 >= b) || cells[y * cols + x] != class {
                continue;
            }
            if !borders_other(cells, cols, rows, x, y) {
                best = Some((d2, (x, y)));
            }
        }
    }
    best.map(|(_, c)| c)
}

/// Whether a cell among the eight around `(x, y)` (those in the grid) is of
/// another class than it.
fn borders_other(cells: &[u8], cols: usize, rows: usize, x: usize, y: usize) -> bool {
    let here = cells[y * cols + x];
    (y.saturating_sub(1)..(y + 2).min(rows))
        .any(|v| (x.saturating_sub(1)..(x + 2).min(cols)).any(|u| cells[v * cols + u] != here))
}

/// The 4×4 pixels `x − 1 ..= x + 2` by `y − 1 ..= y + 2`, centred on the
/// corner between pixels `x` and `x + 1` (and rows `y`, `y + 1`): at
/// `(2 cx, 2 cy)`, on cell `(cx, cy)`'s centre.
fn box_at(x: isize, y: isize) -> [isize; 4] {
    [x - 1, y - 1, x + 3, y + 3]
}

/// [`box_at`] the centre of cell `(x, y)`.
fn cell_box((x, y): (usize, usize)) -> [isize; 4] {
    box_at((2 * x) as isize, (2 * y) as isize)
}

/// Pixel offsets `reach` px along the unit vector of each Sobel gradient
/// `(gx, gy)` of a 0/1 mask (each in −4..=4), rounded: index `(gy + 4) · 9 + gx + 4`.
fn offsets(reach: f32) -> [(isize, isize); 81] {
    let mut table = [(0, 0); 81];
    for (i, o) in table.iter_mut().enumerate() {
        let (gx, gy) = ((i % 9) as f64 - 4.0, (i / 9) as f64 - 4.0);
        let norm = (gx * gx + gy * gy).sqrt();
        if norm > 0.0 {
            let r = f64::from(reach);
            *o = (
                (r * gx / norm).round() as isize,
                (r * gy / norm).round() as isize,
            );
        }
    }
    table
}

/// Refines the cells' mask pixel by pixel in the cells that border the
/// other class (where `s.redo_list` is not empty, only those it lists),
/// adding to `s.changes` (the pixels whose class differs from their cell's,
/// sorted by index; the caller empties it and `s.redo_list` before a first
/// pass). The boundary's normal at a cell is the gradient of the cells'
/// mask over the 3×3 cells around it (Sobel); the two colours are the means
/// of the 4×4 pixels `reach` px (rounded to whole pixels) to either side of
/// the cell's centre along it; a pixel of
/// the cell is instrument where its colour (its own, or where the frame's
/// noise `sigma` is above [`NOISY`] the mean of its 3×3 pixels, which cuts
/// the noise to a third) lies past half way from the outer colour to the
/// inner one. Where the two points do not lie in the two classes (a thin
/// part, a corner, a spike of blurred rim) or the mask has no normal there,
/// the two colours are read instead at the nearest cell of each class whose
/// eight neighbours are all of it ([`nearest_interior`], within
/// `reach / 2 + 2` cells, rounded up, and at most [`MAX_INTERIOR_CELLS`]);
/// where there is none, or the two colours differ by less than
/// `min_contrast` (8-bit units, feature distance), the cells' decision
/// stands. In integers: no rounding decides a pixel.
pub(super) fn refine(
    s: &mut Scratch,
    region: &Region2d,
    cols: usize,
    rows: usize,
    reach: f32,
    min_contrast: f32,
    sigma: f32,
) {
    let (rw, rh) = (region.width, region.height);
    // a pixel's own colour: the mean of its 3×3 pixels where the frame is
    // noisy, else its own (a mean rounds a sharp corner off)
    let noisy = sigma > NOISY;
    let Scratch {
        cells,
        changes,
        near: band,
        near_diff,
        redo_list,
        tail,
        ..
    } = s;
    if reach <= 0.0 || cols * rows == 0 {
        return;
    }
    // a later pass appends to the changes the earlier ones kept (sorted)
    let kept = changes.len();
    // room for every pixel once per region size (and for a later pass's
    // changes while they merge): no allocation per frame
    if changes.capacity() < rw * rh {
        changes.reserve_exact(rw * rh);
    }
    if tail.capacity() < rw * rh {
        tail.reserve_exact(rw * rh);
    }
    // the cells to refine: a neighbour of the other class (in a later pass
    // among `redo_list` alone, below)
    let first = redo_list.is_empty();
    if first {
        mark_band(cells, cols, rows, band, near_diff);
    }
    let offsets = offsets(reach);
    // how far the nearest interior cells are looked for, in cells (at most
    // `MAX_INTERIOR_CELLS`: a long reach must not make each search cost
    // thousands of cells)
    let radius = ((reach / 2.0).ceil() as usize + 2).min(MAX_INTERIOR_CELLS);
    let min2 = f64::from(min_contrast).powi(2);
    let cell = |x: usize, y: usize| -> i32 { i32::from(cells[y * cols + x]) };
    // the cells' decision at a pixel (the samples read it, not the refined one)
    let class_at = |x: usize, y: usize| cells[(y / 2) * cols + x / 2];
    let mut refine_cell = |cx: usize, cy: usize| {
        // toward the instrument: the mask's gradient (Sobel) over the cells
        let (l, r) = (cx.saturating_sub(1), (cx + 1).min(cols - 1));
        let (u, d) = (cy.saturating_sub(1), (cy + 1).min(rows - 1));
        let gx =
            cell(r, u) + 2 * cell(r, cy) + cell(r, d) - cell(l, u) - 2 * cell(l, cy) - cell(l, d);
        let gy =
            cell(l, d) + 2 * cell(cx, d) + cell(r, d) - cell(l, u) - 2 * cell(cx, u) - cell(r, u);
        let (ox, oy) = offsets[((gy + 4) * 9 + gx + 4) as usize];
        // the two colours: the 4×4 pixels centred on the cell's centre
        // (the corner between its pixels) moved by ± the offset, so
        // that both lie exactly as far from it
        let moved =
            |sign: isize| box_at((2 * cx) as isize + sign * ox, (2 * cy) as isize + sign * oy);
        let (inside, outside) = (moved(1), moved(-1));
        // both boxes' centres must lie in the image and in their class
        let centre_class = |b: [isize; 4]| -> Option<u8> {
            let (x, y) = (b[0] + 2, b[1] + 2);
            (x >= 0 && y >= 0 && (x as usize) < rw && (y as usize) < rh)
                .then(|| class_at(x as usize, y as usize))
        };
        let along_normal = (ox, oy) != (0, 0)
            && centre_class(inside) == Some(1)
            && centre_class(outside) == Some(0);
        let (inside, outside) = if along_normal {
            (inside, outside)
        } else {
            // a thin part or a corner: the nearest cells of each class
            // whose neighbours are all of it
            match (
                nearest_interior(cells, cols, rows, cx, cy, 1, radius),
                nearest_interior(cells, cols, rows, cx, cy, 0, radius),
            ) {
                (Some(i), Some(o)) => (cell_box(i), cell_box(o)),
                _ => return,
            }
        };
        let ((s_in, m_in), (s_out, m_out)) = (box_sum(region, inside), box_sum(region, outside));
        let scale = m_in * m_out;
        let outer = s_out.map(|v| v * m_in);
        let delta = [0, 1, 2].map(|k| s_in[k] * m_out - outer[k]);
        let d2: i64 = delta.iter().map(|v| v * v).sum();
        if d2 == 0 || (d2 as f64) < min2 * (scale * scale) as f64 {
            return;
        }
        for py in 2 * cy..(2 * cy + 2).min(rh) {
            for px in 2 * cx..(2 * cx + 2).min(rw) {
                // past half way: (F/m − T)·Δ ≥ |Δ|²/2, times 2 m N²
                let (f, m) = if noisy {
                    let (x, y) = (px as isize, py as isize);
                    box_sum(region, [x - 1, y - 1, x + 2, y + 2])
                } else {
                    let i = region.first + py * region.stride + 3 * px;
                    let p = &region.rgb[i..i + 3];
                    (features([0, 1, 2].map(|k| i64::from(p[k]))), 1)
                };
                let along: i64 = (0..3)
                    .map(|k| (f[k] * scale - m * outer[k]) * delta[k])
                    .sum();
                let v = u8::from(2 * along >= m * d2);
                if v != class_at(px, py) {
                    changes.push(change((py * rw + px) as u32, v));
                }
            }
        }
    };
    if first {
        for cy in 0..rows {
            let row = &band[cy * cols..(cy + 1) * cols];
            // most of a row is far from the boundary: skip eight cells at a time
            let marked = row.chunks(8).enumerate().flat_map(|(k, chunk)| {
                let any = chunk.iter().fold(0u8, |a, &b| a | b) != 0;
                chunk
                    .iter()
                    .enumerate()
                    .filter(move |&(_, &b)| any && b != 0)
                    .map(move |(j, _)| 8 * k + j)
            });
            for cx in marked {
                refine_cell(cx, cy);
            }
        }
    } else {
        // a later pass: the cells around those that moved, where a
        // neighbour is of the other class (`mark_band`'s rule, asked of the
        // few listed cells instead of the whole grid; the others' changes
        // stand)
        for &c in redo_list.iter() {
            let (cx, cy) = (c as usize % cols, c as usize / cols);
            if borders_other(cells, cols, rows, cx, cy) {
                refine_cell(cx, cy);
            }
        }
    }
    // this pass's changes come unsorted (a cell row's pixels in two pixel
    // rows; a later pass's cells in the order they were listed)
    changes[kept..].sort_unstable_by_key(|&c| changed(c).0);
    merge_tail(changes, kept, tail);
}

/// Merges the sorted `changes[..kept]` and `changes[kept..]` in place
/// (by pixel index, which no two share), through `tail`, a copy of the
/// second run: linear in the length, where sorting the whole again was not.
fn merge_tail(changes: &mut [u32], kept: usize, tail: &mut Vec<u32>) {
    if kept == 0 || kept == changes.len() {
        return;
    }
    tail.clear();
    tail.extend_from_slice(&changes[kept..]);
    // from the back: the largest of the two runs' last entries goes last
    let (mut i, mut j, mut k) = (kept, tail.len(), changes.len());
    while j > 0 {
        k -= 1;
        if i > 0 && changed(changes[i - 1]).0 > changed(tail[j - 1]).0 {
            changes[k] = changes[i - 1];
            i -= 1;
        } else {
            changes[k] = tail[j - 1];
            j -= 1;
        }
    }
}

/// After a pass of [`refine`]: gives each instrument cell all of whose
/// pixels that pass changed to tissue their class (the blurred rim of a
/// far or defocused edge is wider than a cell, so the cells' boundary
/// moves out of reach of one pass), marks in `s.redo` (and lists in
/// `s.redo_list`) the cells within one of a cell that changed, and drops
/// their pixels' changes, for [`refine`] to decide again there (it appends
/// their changes). Whether any cell changed. `rw × rh` is the region's size
/// in pixels.
///
/// Only toward tissue, and only whole cells: growing the instrument too, or
/// moving a cell on a majority of its pixels, lost cases on pale, blue-green
/// and yellow tissue (the robustness matrix). A kept change two cells from
/// a moved cell was decided with the cells before the move (its sample
/// boxes may reach into the moved cell); it stands.
pub(super) fn flip_cells(s: &mut Scratch, cols: usize, rw: usize, rh: usize) -> bool {
    let Scratch {
        cells,
        changes,
        redo,
        redo_list,
        to_tissue,
        ..
    } = s;
    let rows = cells.len() / cols.max(1);
    let cell_of = |c: u32| {
        let i = changed(c).0;
        let (x, y) = (i % rw, i / rw);
        (y / 2) * cols + x / 2
    };
    // per cell, its pixels changed to tissue (counted over the changes,
    // which are few beside the cells)
    to_tissue.clear();
    to_tissue.resize(cells.len(), 0);
    for &c in changes.iter() {
        if changed(c).1 == 0 {
            to_tissue[cell_of(c)] += 1;
        }
    }
    redo.clear();
    redo.resize(cells.len(), 0);
    redo_list.clear();
    // each cell listed once at most: no allocation per frame
    if redo_list.capacity() < cells.len() {
        redo_list.reserve_exact(cells.len());
    }
    let mut any = false;
    for &c in changes.iter() {
        let cell = cell_of(c);
        let (cx, cy) = (cell % cols, cell / cols);
        // a cell's pixels: 4, fewer on the region's odd last column or row
        let pixels = (rw - 2 * cx).min(2) * (rh - 2 * cy).min(2);
        if cells[cell] != 1 || usize::from(to_tissue[cell]) != pixels {
            continue;
        }
        cells[cell] = 0;
        any = true;
        // the cells within one of it are decided again
        for y in cy.saturating_sub(1)..(cy + 2).min(rows) {
            for x in cx.saturating_sub(1)..(cx + 2).min(cols) {
                if redo[y * cols + x] == 0 {
                    redo[y * cols + x] = 1;
                    redo_list.push((y * cols + x) as u32);
                }
            }
        }
    }
    if any {
        changes.retain(|&c| redo[cell_of(c)] == 0);
    }
    any
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two sorted runs merge into one sorted list, whatever their lengths
    /// and however they interleave.
    #[test]
    fn merging_the_tail_sorts_the_changes() {
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut tail = Vec::new();
        for (m, k) in [(0, 5), (5, 0), (1, 1), (7, 3), (3, 9), (40, 40)] {
            let mut pixels: Vec<u32> = (0..200).collect();
            // a random choice of m + k distinct pixels, split at random
            for i in (1..pixels.len()).rev() {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                pixels.swap(i, (state % (i as u64 + 1)) as usize);
            }
            let (a, b) = pixels[..m + k].split_at(m);
            let run = |p: &[u32]| {
                let mut r: Vec<u32> = p.iter().map(|&i| change(i, (i % 2) as u8)).collect();
                r.sort_unstable_by_key(|&c| changed(c).0);
                r
            };
            let mut changes = run(a);
            changes.extend(run(b));
            merge_tail(&mut changes, m, &mut tail);
            let mut expected = changes.clone();
            expected.sort_unstable_by_key(|&c| changed(c).0);
            assert_eq!(changes, expected, "runs of {m} and {k}");
            assert_eq!(changes, run(&pixels[..m + k]), "runs of {m} and {k}");
        }
    }

    #[test]
    fn a_whole_box_sums_as_the_clipped_loop_does() {
        // a region inside a wider image (offset and stride), saturated
        // bytes included, every 4×4 box in it and the boxes over its edges
        let (stride_px, width, height, first_px) = (13usize, 9usize, 7usize, 2usize);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let rgb: Vec<u8> = (0..3 * stride_px * (height + 1))
            .map(|i| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                if i % 7 == 0 { 255 } else { (state >> 56) as u8 }
            })
            .collect();
        let region = Region2d {
            rgb: &rgb,
            first: 3 * (stride_px + first_px),
            stride: 3 * stride_px,
            width,
            height,
        };
        for y0 in -2..height as isize {
            for x0 in -2..width as isize {
                let b = [x0, y0, x0 + 4, y0 + 4];
                assert_eq!(
                    box_sum(&region, b),
                    clipped_sum(&region, b),
                    "box at ({x0}, {y0})"
                );
            }
        }
    }

    /// Where the two colours along the boundary's normal do not lie in
    /// their classes (a part one cell thin), the pixels are decided against
    /// the nearest cells of each class whose neighbours are all of it: a
    /// thin rim of steel blurred into the dark lumen (a quarter steel)
    /// becomes tissue, a thin part of steel stays steel. The cells' decision
    /// stood there before.
    #[test]
    fn a_thin_part_is_decided_against_the_nearest_interior_colours() {
        // 40×24 px, 20×12 cells: steel in cells x < 8, lumen elsewhere,
        // but for two arms three cells long at cell rows 4 and 8 (instrument
        // in the cells), a rim that is a quarter steel and a part of steel
        let (rw, rh, cols, rows) = (40usize, 24usize, 20usize, 12usize);
        let (steel, lumen) = ([100.0, 101.0, 106.0], [20.0, 15.0, 15.0]);
        let rim: [f64; 3] = std::array::from_fn(|k| 0.25 * steel[k] + 0.75 * lumen[k]);
        let arm = |x: usize, y: usize| (8..11).contains(&(x / 2)) && [4, 8].contains(&(y / 2));
        let mut rgb = Vec::with_capacity(3 * rw * rh);
        for y in 0..rh {
            for x in 0..rw {
                let c = if x < 16 {
                    steel
                } else if arm(x, y) {
                    if y / 2 == 4 { rim } else { steel }
                } else {
                    lumen
                };
                rgb.extend(c.map(|v: f64| v.round() as u8));
            }
        }
        let region = Region2d {
            rgb: &rgb,
            first: 0,
            stride: 3 * rw,
            width: rw,
            height: rh,
        };
        let cells: Vec<u8> = (0..rows)
            .flat_map(|cy| (0..cols).map(move |cx| u8::from(cx < 8 || arm(2 * cx, 2 * cy))))
            .collect();
        let mut s = Scratch {
            cells,
            ..Scratch::default()
        };
        refine(&mut s, &region, cols, rows, 4.0, 0.2 * 255.0, 0.0);
        let to_tissue: Vec<usize> = s
            .changes
            .iter()
            .map(|&c| changed(c))
            .filter(|&(_, v)| v == 0)
            .map(|(i, _)| i)
            .collect();
        // the rim's tip cell reads its colours along the rim (its normal
        // points back along it, both samples in their classes): it waits for
        // the next pass, when the cells beside it have moved
        let expected: Vec<usize> = (0..rw * rh)
            .filter(|&i| arm(i % rw, i / rw) && (i / rw) / 2 == 4 && (i % rw) / 2 < 10)
            .collect();
        assert_eq!(
            to_tissue, expected,
            "the rim's pixels, and only they, become tissue"
        );
        assert!(
            s.changes.iter().all(|&c| changed(c).1 == 0),
            "no lumen pixel becomes steel"
        );
    }

    /// Only an instrument cell all of whose pixels changed to tissue moves;
    /// the cells within one of it are marked to be decided again and their
    /// changes dropped, the others' kept.
    #[test]
    fn only_whole_instrument_cells_changed_to_tissue_move() {
        // 9×3 pixels: 5×2 cells, the last column and row of cells one pixel
        let (rw, rh, cols) = (9usize, 3usize, 5usize);
        let px = |x: usize, y: usize, v: u8| change((y * rw + x) as u32, v);
        let mut s = Scratch {
            cells: vec![1, 1, 1, 1, 1, 0, 1, 1, 1, 0],
            ..Scratch::default()
        };
        s.changes = vec![
            px(0, 0, 0), // cell (0, 0): all four pixels to tissue
            px(1, 0, 0),
            px(2, 0, 0), // cell (1, 0), beside it: one pixel
            px(6, 0, 0), // cell (3, 0): three of four
            px(7, 0, 0),
            px(0, 1, 0),
            px(1, 1, 0),
            px(6, 1, 0),
            px(8, 2, 1), // cell (4, 1), tissue: its one pixel to instrument
        ];
        s.changes.sort_unstable_by_key(|&c| changed(c).0);
        assert!(flip_cells(&mut s, cols, rw, rh));
        assert_eq!(s.cells, vec![0, 1, 1, 1, 1, 0, 1, 1, 1, 0]);
        assert_eq!(s.redo, vec![1, 1, 0, 0, 0, 1, 1, 0, 0, 0]);
        let kept: Vec<(usize, u8)> = s.changes.iter().map(|&c| changed(c)).collect();
        assert_eq!(kept, vec![(6, 0), (7, 0), (15, 0), (26, 1)]);
        let mut listed = s.redo_list.clone();
        listed.sort_unstable();
        assert_eq!(listed, vec![0, 1, 5, 6]);
        // nothing more to move: no cell changes, nothing to redo
        assert!(!flip_cells(&mut s, cols, rw, rh));
        assert_eq!(s.cells, vec![0, 1, 1, 1, 1, 0, 1, 1, 1, 0]);
        assert!(s.redo_list.is_empty());
        // the region's odd last column and row: cells of two pixels and one
        let (rw, rh, cols) = (3usize, 3usize, 2usize);
        let px = |x: usize, y: usize, v: u8| change((y * rw + x) as u32, v);
        let mut s = Scratch {
            cells: vec![1, 1, 1, 1],
            ..Scratch::default()
        };
        s.changes = vec![px(2, 0, 0), px(2, 1, 0), px(2, 2, 0)];
        assert!(flip_cells(&mut s, cols, rw, rh));
        assert_eq!(s.cells, vec![1, 0, 1, 0]);
        assert_eq!(s.redo, vec![1, 1, 1, 1]);
        assert!(s.changes.is_empty());
    }
}
