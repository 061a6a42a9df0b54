//! The split pyramid: brightness and redness ranges and colour sums of the
//! aligned power-of-two blocks of a region, built bottom-up in one pass
//! (with an AVX2 copy of the same code, chosen at run time).

use super::Scratch;

/// Brightness (`r + g + b`) and redness (`2r − g − b`) ranges of the aligned
/// blocks of one level of the split pyramid, in integer colour units (none at
/// level 0, whose 2×2 cells are never split).
/// Range planes indexed `[brightness, redness]`, blocks row-major.
#[derive(Debug, Default, PartialEq)]
pub(super) struct Level {
    pub(super) cols: usize,
    pub(super) rows: usize,
    pub(super) lo: [Vec<i16>; 2],
    pub(super) hi: [Vec<i16>; 2],
    /// Sums of brightness, redness and `g − b`: 64 bits, as a block of the
    /// largest region (2²⁴ px) sums to 2²⁴ · 765 > 2³¹.
    pub(super) sum: [Vec<i64>; 3],
}

/// A region of an RGB frame: row `y` starts at byte `first + y · stride`.
pub(super) struct Region2d<'a> {
    pub(super) rgb: &'a [u8],
    pub(super) first: usize,
    pub(super) stride: usize,
    pub(super) width: usize,
    pub(super) height: usize,
}

impl Region2d<'_> {
    fn row(&self, y: usize) -> &[u8] {
        &self.rgb[self.first + y * self.stride..][..3 * self.width]
    }
}

/// Combines neighbouring pairs of `v` with `op` onto `out` (an odd last one
/// goes through `alone`).
#[inline(always)]
fn combine_pairs<T: Copy, U>(
    v: &[T],
    op: impl Fn(T, T) -> U,
    alone: impl Fn(T) -> U,
    out: &mut Vec<U>,
) {
    out.extend(v.chunks_exact(2).map(|p| op(p[0], p[1])));
    if let [.., last] = v
        && v.len() % 2 == 1
    {
        out.push(alone(*last));
    }
}

/// Combines each aligned 2×2 group of `src` (`cols × rows`) with `op` into
/// `dst` (a group cut by the edge combines what it has); `vertical` is scratch.
#[inline(always)]
fn reduce_2x2<T: Copy + Default>(
    src: &[T],
    cols: usize,
    op: impl Fn(T, T) -> T,
    dst: &mut Vec<T>,
    vertical: &mut Vec<T>,
) {
    dst.clear();
    vertical.clear();
    vertical.resize(cols, T::default());
    for pair in src.chunks(2 * cols) {
        let (a, b) = pair.split_at(cols.min(pair.len()));
        if b.is_empty() {
            // a last row alone (op is not idempotent: sums)
            vertical.copy_from_slice(a);
        } else {
            for ((v, &p), &q) in vertical.iter_mut().zip(a).zip(b) {
                *v = op(p, q);
            }
        }
        combine_pairs(vertical, &op, |t| t, dst);
    }
}

/// Per-pixel features of a row of RGB: brightness `r + g + b`, redness
/// `2r − g − b` and `g − b` (the three determine the colour); each plane of
/// `out` is a row long.
#[inline(always)]
fn features(row: &[u8], out: &mut [Vec<i16>; 3]) {
    let [bright, red, gb] = out;
    for (((c, b), r), d) in row
        .chunks_exact(3)
        .zip(bright.iter_mut())
        .zip(red.iter_mut())
        .zip(gb.iter_mut())
    {
        let (x, y, z) = (i16::from(c[0]), i16::from(c[1]), i16::from(c[2]));
        *b = x + y + z;
        *r = 2 * x - y - z;
        *d = y - z;
    }
}

/// Builds the split pyramid of the region in `s.levels`: 2×2 cells first, each
/// level above from the one below, up to a single block. Returns the number of
/// levels.
pub(super) fn pyramid(region: &Region2d, s: &mut Scratch) -> usize {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2, checked just above.
        return unsafe { pyramid_avx2(region, s) };
    }
    pyramid_portable(region, s)
}

/// [`pyramid`] compiled for AVX2: its byte shuffles take the RGB triples apart
/// many pixels at a time (the x86-64 baseline has none) and its min, max and
/// sums run 16 lanes wide.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn pyramid_avx2(region: &Region2d, s: &mut Scratch) -> usize {
    pyramid_portable(region, s)
}

#[inline(always)]
fn pyramid_portable(region: &Region2d, s: &mut Scratch) -> usize {
    let (rw, rh) = (region.width, region.height);
    let (cols, cell_rows) = (rw.div_ceil(2), rh.div_ceil(2));
    let depth = {
        // levels until one block: 2×2 cells, then halving
        let mut n = 1;
        let (mut c, mut r) = (cols, cell_rows);
        while c > 1 || r > 1 {
            (c, r) = (c.div_ceil(2), r.div_ceil(2));
            n += 1;
        }
        n
    };
    if s.levels.len() < depth {
        s.levels.resize_with(depth, Level::default);
    }
    let Scratch {
        levels,
        features: [fa, fb],
        cell_ranges,
        narrow: v,
        narrow_cells: w,
        wide,
        ..
    } = s;
    for plane in fa.iter_mut().chain(fb.iter_mut()) {
        plane.clear();
        plane.resize(rw, 0);
    }
    v.clear();
    v.resize(rw, 0);
    w.clear();
    w.resize(cols, 0);
    let (base, above) = levels.split_at_mut(1);
    let base = &mut base[0];
    (base.cols, base.rows) = (cols, cell_rows);
    for plane in base.sum.iter_mut() {
        plane.clear();
    }
    // level 1 (4×4 blocks) takes its ranges straight from pairs of cell rows
    let mut level1 = above.first_mut();
    if let Some(l1) = level1.as_deref_mut() {
        (l1.cols, l1.rows) = (cols.div_ceil(2), cell_rows.div_ceil(2));
        for plane in l1.lo.iter_mut().chain(l1.hi.iter_mut()) {
            plane.clear();
        }
    }
    let [even, odd] = cell_ranges;
    for cy in 0..cell_rows {
        features(region.row(2 * cy), fa);
        let single = 2 * cy + 1 >= rh;
        if single {
            fb.clone_from(fa);
        } else {
            features(region.row(2 * cy + 1), fb);
        }
        for k in 0..3 {
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = if single { p } else { p + q };
            }
            let wide_add = |p: i16, q: i16| i64::from(p) + i64::from(q);
            combine_pairs(v, wide_add, i64::from, &mut base.sum[k]);
        }
        let Some(l1) = level1.as_deref_mut() else {
            continue;
        };
        let ranges = if cy % 2 == 0 { &mut *even } else { &mut *odd };
        for k in 0..2 {
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = p.min(q);
            }
            ranges[0][k].clear();
            combine_pairs(v, i16::min, |t| t, &mut ranges[0][k]);
            for ((v, &p), &q) in v.iter_mut().zip(&fa[k]).zip(&fb[k]) {
                *v = p.max(q);
            }
            ranges[1][k].clear();
            combine_pairs(v, i16::max, |t| t, &mut ranges[1][k]);
        }
        if cy % 2 == 1 || cy + 1 == cell_rows {
            let second = if cy % 2 == 1 { &*odd } else { &*even };
            for k in 0..2 {
                for ((w, &p), &q) in w.iter_mut().zip(&even[0][k]).zip(&second[0][k]) {
                    *w = p.min(q);
                }
                combine_pairs(w, i16::min, |t| t, &mut l1.lo[k]);
                for ((w, &p), &q) in w.iter_mut().zip(&even[1][k]).zip(&second[1][k]) {
                    *w = p.max(q);
                }
                combine_pairs(w, i16::max, |t| t, &mut l1.hi[k]);
            }
        }
    }
    for n in 1..depth {
        let (below, rest) = levels.split_at_mut(n);
        let (src, dst) = (&below[n - 1], &mut rest[0]);
        let c = src.cols;
        (dst.cols, dst.rows) = (c.div_ceil(2), src.rows.div_ceil(2));
        for k in 0..3 {
            reduce_2x2(&src.sum[k], c, |p, q| p + q, &mut dst.sum[k], wide);
        }
        if n > 1 {
            for k in 0..2 {
                reduce_2x2(&src.lo[k], c, i16::min, &mut dst.lo[k], v);
                reduce_2x2(&src.hi[k], c, i16::max, &mut dst.hi[k], v);
            }
        }
    }
    depth
}

#[cfg(test)]
mod tests {
    use super::*;

    fn region(rgb: &[u8], w: usize, h: usize) -> Region2d<'_> {
        Region2d {
            rgb,
            first: 0,
            stride: 3 * w,
            width: w,
            height: h,
        }
    }

    /// The vectorised pyramid (AVX2, where the CPU has it) equals the portable one.
    #[test]
    fn pyramid_is_the_same_on_every_code_path() {
        for (w, h) in [(1, 1), (3, 2), (17, 9), (64, 48), (101, 77)] {
            let rgb: Vec<u8> = (0..w * h * 3)
                .map(|i: usize| (i.wrapping_mul(2_654_435_761) >> 7) as u8)
                .collect();
            let (mut fast, mut portable) = (Scratch::default(), Scratch::default());
            let depth = pyramid(&region(&rgb, w, h), &mut fast);
            assert_eq!(depth, pyramid_portable(&region(&rgb, w, h), &mut portable));
            assert_eq!(fast.levels[..depth], portable.levels[..depth], "{w}×{h}");
            let top = &fast.levels[depth - 1];
            assert_eq!((top.cols, top.rows), (1, 1));
            // the top block's sums are the sums over all pixels
            let bright: i64 = rgb.iter().map(|&c| i64::from(c)).sum();
            assert_eq!(top.sum[0], vec![bright], "{w}×{h}");
        }
    }
}
