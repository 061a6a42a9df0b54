//! Shading the instrument: polished steel lit by the endoscope's light at
//! the camera (a diffuse term, a sharp highlight and a broad sheen), tinted
//! by the tissue it reflects (Schlick's Fresnel), matte tape, and the tape
//! band along the instrument's arc length.

use nalgebra::Vector3;

use super::Occlusion;
use crate::camera::Camera;
use crate::instrument::{Ends, Part};
use crate::raster::{CameraBody, SurfaceHit};

/// Base colour of the instrument's steel, linear RGB in [0, 1].
const METAL: [f32; 3] = [0.60, 0.62, 0.66];
/// Base colour of the tape: matte red.
const TAPE: [f32; 3] = [0.55, 0.05, 0.06];
/// Reflectance of steel at normal incidence (Schlick's `F₀`).
const STEEL_F0: f64 = 0.55;
/// Distance at which the endoscope's light gives the nominal exposure, mm;
/// the irradiance falls as its inverse square (capped at 2.5 up close).
pub(super) const LIGHT_MM: f64 = 30.0;

/// The endoscope light's strength on the instrument, in linear light at the
/// nominal distance: chosen with the camera's response (BT.709) so that
/// steel at 10 mm shows about 0.6 of full scale, at 30 mm 0.4 and at 50 mm
/// 0.25 (the tissue's strength is part of each background's look).
const INSTRUMENT_LIGHT: f64 = 0.5;

/// The light's falloff at distance `t_mm` from the camera: `(30/t)²`, at most 2.5.
#[inline]
pub(super) fn falloff(t_mm: f64) -> f64 {
    (LIGHT_MM / t_mm.max(1.0)).powi(2).min(2.5)
}

/// [`falloff`] in `f32`, as the instrument's shading makes it (the AVX2
/// copy in [`steel_colours_avx2`] makes the same operations).
#[inline]
fn falloff_f32(t_mm: f32) -> f32 {
    let fall = LIGHT_MM as f32 / t_mm.max(1.0);
    (fall * fall).min(2.5)
}

/// What the steel reflects: the tissue in front of the camera (the
/// background image, full frame, linear RGB), and its mean colour.
pub(super) struct Surroundings<'a> {
    pub(super) camera: &'a Camera,
    pub(super) image: &'a [f32],
    pub(super) mean: [f32; 3],
}

impl Surroundings<'_> {
    /// The tissue seen along the reflected ray `r` (camera frame): where it
    /// points ahead, the background pixel it would project to, lens
    /// included (clamped to the frame; the mean colour where the image is
    /// not the camera's); where it points back past the camera, the dark
    /// overtube and shadowed tissue around it.
    #[inline]
    fn along(&self, [rx, ry, rz]: [f32; 3]) -> [f32; 3] {
        if rz < 0.05 {
            return self.mean.map(|c| 0.3 * c);
        }
        let k = &self.camera.intrinsics;
        // Lens::distort of the pinhole direction, in f32
        let (xu, yu) = (rx / rz, ry / rz);
        let ru2 = xu * xu + yu * yu;
        let root = (1.0 - 4.0 * self.camera.lens.division as f32 * ru2)
            .max(0.0)
            .sqrt();
        let s = 2.0 / (1.0 + root);
        let pu = k.fx as f32 * (xu * s) + k.cx as f32;
        let pv = k.fy as f32 * (yu * s) + k.cy as f32;
        let u = pu.clamp(0.0, k.width as f32 - 1.0) as i32;
        let v = pv.clamp(0.0, k.height as f32 - 1.0) as i32;
        let i = 3 * (v as usize * k.width as usize + u as usize);
        match self.image.get(i..i + 3) {
            Some(p) => [p[0], p[1], p[2]],
            None => self.mean,
        }
    }

    /// Whether the image is the camera's whole frame (so that every
    /// clamped pixel is in it), with every value's index within `i32` (the
    /// AVX2 copy computes them in 32 bits; a valid camera's sides are at
    /// most 16,384 px, so this always holds for one).
    fn whole(&self) -> bool {
        let k = &self.camera.intrinsics;
        let values = 3 * k.width as usize * k.height as usize;
        values <= i32::MAX as usize && self.image.len() >= values
    }
}

/// Whether the surface at `hit` lies under the tape band `tape` (arc lengths).
pub(super) fn under_tape(hit: &SurfaceHit, tape: Option<(f32, f32)>) -> bool {
    let arc = hit.arc_mm as f32;
    tape.is_some_and(|(lo, hi)| arc >= lo && arc <= hi)
}

/// The colour of the surface at `hit`, seen along unit `d`: tape where
/// [`under_tape`], else steel; `env` is what the steel reflects. Frames
/// make their colours by [`LookQueue`]; this one-at-a-time form is the
/// reference its test holds them to.
#[cfg(test)]
fn surface_colour(
    bodies: &[CameraBody],
    hit: &SurfaceHit,
    d: &Vector3<f64>,
    tape: Option<(f32, f32)>,
    env: &Surroundings<'_>,
) -> [f32; 3] {
    let (d, n, t) = f32_inputs(hit, d);
    if under_tape(hit, tape) {
        return tape_colour(d, n, t);
    }
    let (shadow, gloss) = steel_finish(bodies, hit);
    steel_colour(d, n, t, shadow, gloss, env)
}

/// Steel's colour where a ray along unit `d` meets it at distance `t` (mm),
/// outward normal `n`, with `shadow` and `gloss` ([`steel_finish`]): the
/// endoscope's light, diffuse and a highlight, plus the tissue it reflects.
/// In `f32`, each operation the one [`LookQueue`]'s AVX2 copy makes, in its
/// order (no fused multiply-add; the powers by squarings), so the same bits.
fn steel_colour(
    d: [f32; 3],
    n: [f32; 3],
    t: f32,
    shadow: f32,
    gloss: f32,
    env: &Surroundings<'_>,
) -> [f32; 3] {
    let fall = falloff_f32(t);
    let nd = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
    let cos = (-nd).clamp(0.0, 1.0);
    let light = INSTRUMENT_LIGHT as f32 * fall;
    // Schlick: (1 − cos)⁵ = x · x⁴
    let x = 1.0 - cos;
    let x2 = x * x;
    let fresnel = STEEL_F0 as f32 + (1.0 - STEEL_F0 as f32) * (x * (x2 * x2));
    // satin steel scatters some light back even at grazing incidence
    let diffuse = (0.28 + 0.42 * cos) * light * shadow;
    // the mirror direction d − n (2 n·d)
    let twice = 2.0 * nd;
    let r = [0, 1, 2].map(|k| d[k] - n[k] * twice);
    // the tissue it reflects is lit about as the steel is (no brighter than nominal)
    let reflected = 0.22 * fresnel * shadow * gloss * fall.min(1.0);
    // cos⁸⁰ = cos¹⁶ · cos⁶⁴ and cos¹⁰ = cos² · cos⁸, their bases held
    // above where the powers would fall to subnormal numbers, which cost the
    // processor a hundred cycles each (the terms are then below 1e-30: nothing)
    let (g, s) = (cos.max(GLINT_FLOOR), cos.max(SHEEN_FLOOR));
    let (g2, s2) = (g * g, s * s);
    let (g4, s4) = (g2 * g2, s2 * s2);
    let (g8, s8) = (g4 * g4, s4 * s4);
    let g16 = g8 * g8;
    let g32 = g16 * g16;
    let g64 = g32 * g32;
    let shine = 0.9 * (g16 * g64) + 0.2 * (s2 * s8);
    let highlight = shine * light * shadow * gloss;
    let seen = env.along(r);
    [0, 1, 2].map(|k| METAL[k] * diffuse + seen[k] * reflected + highlight)
}

/// The least base of the highlight's `cos⁸⁰`: 0.4⁸⁰ ≈ 1.5e-32, still a
/// normal `f32` (the smallest is 1.2e-38).
const GLINT_FLOOR: f32 = 0.4;
/// The least base of the sheen's `cos¹⁰`: 0.001¹⁰ = 1e-30.
const SHEEN_FLOOR: f32 = 1e-3;

/// The tape's colour where a ray along unit `d` meets it at distance `t`
/// (mm), outward normal `n`: matte, Lambert and a faint sheen.
fn tape_colour(d: [f32; 3], n: [f32; 3], t: f32) -> [f32; 3] {
    let light = INSTRUMENT_LIGHT as f32 * falloff_f32(t);
    let cos = (-(n[0] * d[0] + n[1] * d[1] + n[2] * d[2])).clamp(0.0, 1.0);
    let diffuse = (0.15 + 0.85 * cos) * light;
    // cos¹⁶, its base held above subnormal powers (0.01¹⁶ = 1e-32)
    let c2 = cos.max(0.01) * cos.max(0.01);
    let c4 = c2 * c2;
    let c8 = c4 * c4;
    let sheen = 0.04 * (c8 * c8) * light;
    TAPE.map(|c| c * diffuse + sheen)
}

/// A hit's ray, normal and distance in `f32`, as the shading reads them.
fn f32_inputs(hit: &SurfaceHit, d: &Vector3<f64>) -> ([f32; 3], [f32; 3], f32) {
    let f = |v: &Vector3<f64>| [v.x as f32, v.y as f32, v.z as f32];
    (f(d), f(&hit.normal), hit.t as f32)
}

/// The steel's finish at `hit`: the shadow on it (the backbone, seen
/// through the gaps between discs, sits in their shadow) and its gloss
/// (machined disc faces are duller than the polished sides).
fn steel_finish(bodies: &[CameraBody], hit: &SurfaceHit) -> (f32, f32) {
    let body = &bodies[hit.body];
    let shadow = if matches!(body.part, Part::Link(_)) && body.ends == Ends::Round {
        0.45
    } else {
        1.0
    };
    let gloss = if hit.on_end && body.ends == Ends::Flat {
        0.3
    } else {
        1.0
    };
    (shadow, gloss)
}

/// How many looks [`LookQueue`] holds before it makes them (a multiple of eight).
const QUEUE: usize = 64;

/// A frame's looks, queued while the tiles are walked and made a batch at a
/// time into the colours of the pixels they shade (a kept batch in the
/// first cache level, not a frame's worth of looks in memory).
///
/// Steel's colours are made eight to an instruction where the processor
/// has AVX2, as [`steel_colour`] makes them one at a time (the same bits; a
/// test holds them equal), the reflected pixels read one at a time (a gather
/// instruction is slower on processors whose microcode guards it). Then the queue's
/// looks, in the order they came, go into their pixels: an inner pixel
/// takes its look's colour, an edge's pixel adds a quarter of each of its
/// four rays' (from black, in their order).
#[derive(Debug, Clone)]
pub(super) struct LookQueue {
    /// Steel's inputs, a field to a row: ray (x, y, z), normal (x, y, z),
    /// distance, shadow, gloss; one lane a look.
    rows: [[f32; QUEUE]; 9],
    /// Lanes of steel queued.
    steel: usize,
    /// Each queued look: its pixel (index in the patches), whether it is one
    /// of an edge's rays, and its steel lane (`u32::MAX`: its colour is in `done`).
    patch: [u32; QUEUE],
    edge: [bool; QUEUE],
    lane: [u32; QUEUE],
    done: [[f32; 3]; QUEUE],
    /// Looks queued.
    len: usize,
    /// Makes steel's colours one at a time even where the processor has
    /// AVX2 (the tests hold both ways to the same bits).
    portable: bool,
    /// The steel lanes' colours, a channel to a row, once made.
    colours: [[f32; QUEUE]; 3],
}

impl Default for LookQueue {
    fn default() -> Self {
        Self {
            rows: [[0.0; QUEUE]; 9],
            steel: 0,
            patch: [0; QUEUE],
            edge: [false; QUEUE],
            lane: [0; QUEUE],
            done: [[0.0; 3]; QUEUE],
            len: 0,
            portable: false,
            colours: [[0.0; QUEUE]; 3],
        }
    }
}

impl LookQueue {
    /// Queues the look at `hit` seen along unit `d` for the pixel
    /// `patches[patch]` (one of its four rays if `edge`): tape's is made at
    /// once, steel's with its batch. Makes the batch when the queue is full.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn push(
        &mut self,
        bodies: &[CameraBody],
        hit: &SurfaceHit,
        d: &Vector3<f64>,
        tape: Option<(f32, f32)>,
        (patch, edge): (u32, bool),
        env: &Surroundings<'_>,
        patches: &mut [(u32, [f32; 3])],
    ) {
        let (d, n, t) = f32_inputs(hit, d);
        if under_tape(hit, tape) {
            self.push_colour(tape_colour(d, n, t), (patch, edge), env, patches);
            return;
        }
        let (shadow, gloss) = steel_finish(bodies, hit);
        let q = self.steel;
        for (row, v) in self
            .rows
            .iter_mut()
            .zip([d[0], d[1], d[2], n[0], n[1], n[2], t, shadow, gloss])
        {
            row[q] = v;
        }
        self.steel += 1;
        self.enqueue((patch, edge), q as u32, [0.0; 3], env, patches);
    }

    /// Queues the colour `c` (linear RGB) for the pixel `patches[patch]`
    /// (one of its four rays if `edge`).
    #[inline]
    pub(super) fn push_colour(
        &mut self,
        c: [f32; 3],
        (patch, edge): (u32, bool),
        env: &Surroundings<'_>,
        patches: &mut [(u32, [f32; 3])],
    ) {
        self.enqueue((patch, edge), u32::MAX, c, env, patches);
    }

    #[inline(always)]
    fn enqueue(
        &mut self,
        (patch, edge): (u32, bool),
        lane: u32,
        c: [f32; 3],
        env: &Surroundings<'_>,
        patches: &mut [(u32, [f32; 3])],
    ) {
        let i = self.len;
        self.patch[i] = patch;
        self.edge[i] = edge;
        self.lane[i] = lane;
        self.done[i] = c;
        self.len += 1;
        if self.len == QUEUE {
            self.flush(env, patches);
        }
    }

    /// Empties the queue, dropping what it holds (a frame starts with it:
    /// a frame cut short leaves no look for the next one's pixels).
    pub(super) fn clear(&mut self) {
        self.len = 0;
        self.steel = 0;
    }

    /// Makes the queued looks and puts them into their pixels' colours in
    /// `patches`; the queue is empty after.
    pub(super) fn flush(&mut self, env: &Surroundings<'_>, patches: &mut [(u32, [f32; 3])]) {
        self.make(env);
        let [r, g, b] = &self.colours;
        for i in 0..self.len {
            let lane = self.lane[i] as usize;
            let c = if lane < QUEUE {
                [r[lane], g[lane], b[lane]]
            } else {
                self.done[i]
            };
            let Some((_, px)) = patches.get_mut(self.patch[i] as usize) else {
                continue;
            };
            if self.edge[i] {
                (0..3).for_each(|ch| px[ch] += 0.25 * c[ch]);
            } else {
                *px = c;
            }
        }
        self.len = 0;
        self.steel = 0;
    }

    /// Makes the steel lanes' colours into `colours`.
    fn make(&mut self, env: &Surroundings<'_>) {
        let [r, g, b] = &mut self.colours;
        steel_colours(
            self.rows.each_ref().map(|row| &row[..]),
            self.steel,
            [r, g, b],
            env,
            self.portable,
        );
    }
}

/// Steel's colours ([`steel_colour`]) of the first `n` lanes of `rows`
/// (ray x, y, z, normal x, y, z, distance, shadow, gloss; each row as long
/// as `out`'s, at least `n` rounded up to eight), into `out` (red, green,
/// blue): eight at a time in AVX2 where the processor has it and `env`'s
/// image is the whole frame (unless `portable`), with the same bits (a test
/// holds them equal). Lanes past `n` up to the next eighth are made too
/// (from whatever finite values they hold) and may be dropped.
pub(super) fn steel_colours(
    rows: [&[f32]; 9],
    n: usize,
    out: [&mut [f32]; 3],
    env: &Surroundings<'_>,
    portable: bool,
) {
    let len = (out.iter().map(|r| r.len()))
        .chain(rows.iter().map(|r| r.len()))
        .min()
        .unwrap_or(0);
    #[cfg(target_arch = "x86_64")]
    if !portable
        && n.div_ceil(8) * 8 <= len
        && env.whole()
        && std::arch::is_x86_feature_detected!("avx2")
    {
        // SAFETY: the processor has AVX2 and the image is the camera's whole
        // frame, checked just above, and every row holds `n` rounded up to eight.
        unsafe { steel_colours_avx2(rows, n, out, env) };
        return;
    }
    let _ = portable;
    let [red, green, blue] = out;
    for q in 0..n.min(len) {
        let r = |i: usize| rows[i][q];
        let c = steel_colour(
            [r(0), r(1), r(2)],
            [r(3), r(4), r(5)],
            r(6),
            r(7),
            r(8),
            env,
        );
        (red[q], green[q], blue[q]) = (c[0], c[1], c[2]);
    }
}

/// [`steel_colours`] eight at a time in AVX2 (the lanes' pixels are
/// clamped into the image whatever values they hold).
///
/// # Safety
/// The processor has AVX2, `env`'s image is the camera's whole frame
/// ([`Surroundings::whole`]), and every row holds `n` rounded up to eight.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn steel_colours_avx2(
    rows: [&[f32]; 9],
    n: usize,
    out: [&mut [f32]; 3],
    env: &Surroundings<'_>,
) {
    use std::arch::x86_64::{
        _CMP_GT_OQ, _CMP_LT_OQ, _mm256_add_epi32, _mm256_add_ps as add, _mm256_blendv_ps,
        _mm256_cmp_ps, _mm256_cvttps_epi32, _mm256_div_ps as div, _mm256_loadu_ps, _mm256_max_ps,
        _mm256_min_ps, _mm256_movemask_ps, _mm256_mul_ps as mul, _mm256_mullo_epi32,
        _mm256_set1_epi32, _mm256_set1_ps as v, _mm256_sqrt_ps, _mm256_storeu_ps,
        _mm256_storeu_si256, _mm256_sub_ps as sub, _mm256_xor_ps,
    };
    // (closures here would not inherit AVX2 and stay out of line)
    macro_rules! sq {
        ($x:expr) => {{
            let x = $x;
            mul(x, x)
        }};
    }
    let k = &env.camera.intrinsics;
    let (fx, cx, fy, cy) = (
        v(k.fx as f32),
        v(k.cx as f32),
        v(k.fy as f32),
        v(k.cy as f32),
    );
    let four_division = v(4.0 * env.camera.lens.division as f32);
    let (u_max, v_max) = (v(k.width as f32 - 1.0), v(k.height as f32 - 1.0));
    let (width, three) = (_mm256_set1_epi32(k.width as i32), _mm256_set1_epi32(3));
    let behind_colour = env.mean.map(|c| 0.3 * c);
    let image = env.image.as_ptr();
    let (zero, one, two) = (v(0.0), v(1.0), v(2.0));
    let [red, green, blue] = out;
    for b in (0..n).step_by(8) {
        let r = &rows;
        macro_rules! row {
            // SAFETY: every row holds `n` rounded up to eight values (the
            // caller's promise), so eight from `b`.
            ($i:expr) => {
                unsafe { _mm256_loadu_ps(r[$i].as_ptr().add(b)) }
            };
        }
        let (dx, dy, dz, nx, ny, nz) = (row!(0), row!(1), row!(2), row!(3), row!(4), row!(5));
        let (t, shadow, gloss) = (row!(6), row!(7), row!(8));
        let fall = div(v(LIGHT_MM as f32), _mm256_max_ps(t, one));
        let fall = _mm256_min_ps(sq!(fall), v(2.5));
        let nd = add(add(mul(nx, dx), mul(ny, dy)), mul(nz, dz));
        // clamp(−n·d, 0, 1), NaN kept as `clamp` keeps it
        let c = _mm256_xor_ps(nd, v(-0.0));
        let c = _mm256_blendv_ps(c, zero, _mm256_cmp_ps::<_CMP_LT_OQ>(c, zero));
        let cos = _mm256_blendv_ps(c, one, _mm256_cmp_ps::<_CMP_GT_OQ>(c, one));
        let light = mul(v(INSTRUMENT_LIGHT as f32), fall);
        let x = sub(one, cos);
        let fresnel = add(
            v(STEEL_F0 as f32),
            mul(v(1.0 - STEEL_F0 as f32), mul(x, sq!(sq!(x)))),
        );
        let diffuse = mul(mul(add(v(0.28), mul(v(0.42), cos)), light), shadow);
        let twice = mul(two, nd);
        let (rx, ry, rz) = (
            sub(dx, mul(nx, twice)),
            sub(dy, mul(ny, twice)),
            sub(dz, mul(nz, twice)),
        );
        let reflected = mul(
            mul(mul(mul(v(0.22), fresnel), shadow), gloss),
            _mm256_min_ps(fall, one),
        );
        let g2 = sq!(_mm256_max_ps(cos, v(GLINT_FLOOR)));
        let g16 = sq!(sq!(sq!(g2)));
        let g64 = sq!(sq!(g16));
        let s2 = sq!(_mm256_max_ps(cos, v(SHEEN_FLOOR)));
        let s8 = sq!(sq!(s2));
        let shine = add(mul(v(0.9), mul(g16, g64)), mul(v(0.2), mul(s2, s8)));
        let highlight = mul(mul(mul(shine, light), shadow), gloss);
        // the reflected pixel (Surroundings::along): the lens, the clamp
        // (NaN to 0 as `as i32` takes it), its index
        let (xu, yu) = (div(rx, rz), div(ry, rz));
        let ru2 = add(mul(xu, xu), mul(yu, yu));
        let root = _mm256_sqrt_ps(_mm256_max_ps(sub(one, mul(four_division, ru2)), zero));
        let s = div(two, add(one, root));
        let (pu, pv) = (add(mul(fx, mul(xu, s)), cx), add(mul(fy, mul(yu, s)), cy));
        let u = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(pu, zero), u_max));
        let vv = _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(pv, zero), v_max));
        let at = _mm256_mullo_epi32(three, _mm256_add_epi32(_mm256_mullo_epi32(vv, width), u));
        // ahead of the camera (not `rz < 0.05`, NaN included, as `along` asks)
        let behind = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(rz, v(0.05)));
        let mut index = [0i32; 8];
        // SAFETY: `index` holds eight values.
        unsafe { _mm256_storeu_si256(index.as_mut_ptr().cast(), at) };
        // the reflected pixels read one by one (a gather is slower on
        // processors whose microcode guards it)
        let mut seen = [[0.0f32; 8]; 3];
        for (q, &i) in index.iter().enumerate() {
            let c = if behind & (1 << q) != 0 {
                behind_colour
            } else {
                let i = i as usize;
                // SAFETY: every index is a clamped pixel's red value in
                // the whole frame, which the image holds (the caller's promise).
                unsafe { [*image.add(i), *image.add(i + 1), *image.add(i + 2)] }
            };
            (seen[0][q], seen[1][q], seen[2][q]) = (c[0], c[1], c[2]);
        }
        for (ch, row) in [&mut *red, &mut *green, &mut *blue].into_iter().enumerate() {
            // SAFETY: `seen[ch]` holds eight values.
            let seen = unsafe { _mm256_loadu_ps(seen[ch].as_ptr()) };
            let colour = add(
                add(mul(v(METAL[ch]), diffuse), mul(seen, reflected)),
                highlight,
            );
            // SAFETY: as the loads.
            unsafe { _mm256_storeu_ps(row.as_mut_ptr().add(b), colour) };
        }
    }
}

/// The arc-length band `[lo, hi]` holding `o.fraction` of `arcs` (the
/// instrument's pixels in the region the share is measured over), placed at
/// `o.position`: 0 starting at the nearest, 1 ending at the farthest arc length.
pub(super) fn tape_band(arcs: &mut [f32], o: Occlusion) -> Option<(f32, f32)> {
    let n = arcs.len();
    if n == 0 || o.fraction <= 0.0 {
        return None;
    }
    let count = ((o.fraction * n as f64).round() as usize).min(n);
    if count == 0 {
        return None;
    }
    let start = (o.position * (n - count) as f64).round() as usize;
    // the start-th and (start + count − 1)-th smallest, without a full sort
    let (_, &mut lo, above) = arcs.select_nth_unstable_by(start, f32::total_cmp);
    let hi = if count == 1 {
        lo
    } else {
        *above.select_nth_unstable_by(count - 2, f32::total_cmp).1
    };
    Some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::instrument::Instrument;
    use crate::raster::Rasterizer;
    use crate::roi::Roi;

    /// A colour's bits.
    fn bits(c: [f32; 3]) -> [u32; 3] {
        c.map(f32::to_bits)
    }

    /// The tape's band takes `fraction` of the pixels' arcs, placed by
    /// `position`: the middle one leaves as many pixels before it as after
    /// it, the distal one ends at the tip (the largest arc), the proximal
    /// one starts at the smallest.
    #[test]
    fn the_tape_band_is_placed_along_the_pixels_it_covers() {
        // 1,000 pixels' arcs, out of order, 0.1 mm apart
        let arcs: Vec<f32> = (0..1000).map(|i| ((i * 379) % 1000) as f32 * 0.1).collect();
        let band = |fraction: f64, position: f64| {
            let (lo, hi) =
                tape_band(&mut arcs.clone(), Occlusion::new(fraction, position)).expect("a band");
            let before = arcs.iter().filter(|&&a| a < lo).count();
            let inside = arcs.iter().filter(|&&a| a >= lo && a <= hi).count();
            let after = arcs.iter().filter(|&&a| a > hi).count();
            (before, inside, after)
        };
        assert_eq!(band(0.2, 0.5), (400, 200, 400));
        assert_eq!(band(0.4, 0.5), (300, 400, 300));
        assert_eq!(band(0.4, 1.0), (600, 400, 0));
        assert_eq!(band(0.4, 0.0), (0, 400, 600));
        assert_eq!(band(0.7, 0.3), (90, 700, 210));
        // no tape: no band
        assert_eq!(tape_band(&mut arcs.clone(), Occlusion::new(0.0, 0.5)), None);
        assert_eq!(tape_band(&mut [], Occlusion::new(0.4, 0.5)), None);
    }

    /// The far tip was once lost because the light fell off on the steel
    /// but not on the tissue behind it: both now take one falloff. A tissue
    /// plane facing the camera and steel facing it, each moved from 30 to
    /// 60 mm, keep their colours' ratio: each darkens by (30/60)². (Nearer
    /// than 30 mm the steel's reflection of the tissue stays at its nominal
    /// light, `fall.min(1)`, as the tissue it reflects is no brighter than
    /// nominal: the two then part, by design.)
    #[test]
    fn tissue_and_steel_darken_alike_with_distance() {
        use super::super::background::{light, look};
        use crate::Background;
        let camera = Camera::default();
        let (w, h) = (8, 8);
        let image = vec![0.5f32; 3 * w * h];
        let env = Surroundings {
            camera: &camera,
            image: &image,
            mean: [0.5; 3],
        };
        let tissue = |z: f32| {
            let mut img = vec![1.0f32; 3 * w * h];
            light(&mut img, &vec![z; w * h], w, h, &look(Background::Colon));
            // a pixel beside the centre: its ray is all but along the axis
            img[3 * (h / 2 * w + w / 2)]
        };
        let steel = |t: f32| steel_colour([0.0, 0.0, 1.0], [0.0, 0.0, -1.0], t, 1.0, 1.0, &env);
        let expected = (30.0f32 / 60.0).powi(2);
        let tissue_ratio = tissue(60.0) / tissue(30.0);
        assert!(
            (tissue_ratio / expected - 1.0).abs() < 1e-3,
            "tissue {tissue_ratio}"
        );
        for (far, near) in steel(60.0).iter().zip(steel(30.0)) {
            let steel_ratio = far / near;
            assert!(
                (steel_ratio / tissue_ratio - 1.0).abs() < 1e-3,
                "steel {steel_ratio} vs tissue {tissue_ratio}"
            );
        }
    }

    /// The queued looks (AVX2 where the processor has it, and the portable
    /// copy) give, pixel for pixel, the bits of [`surface_colour`]'s colours:
    /// steel and tape, centre and off-centre rays, reflections ahead and
    /// behind the camera, batches full and part full; an edge's pixel the
    /// sum of a quarter of each of its four rays' colours, in order.
    #[test]
    fn queued_looks_are_the_one_at_a_time_looks() {
        let camera = Camera::default();
        let k = camera.intrinsics;
        let (w, h) = (k.width as usize, k.height as usize);
        let image: Vec<f32> = (0..3 * w * h).map(|i| (i % 97) as f32 / 97.0).collect();
        let env = Surroundings {
            camera: &camera,
            image: &image,
            mean: [0.4, 0.2, 0.1],
        };
        let mut raster = Rasterizer::new();
        let (mut steel, mut taped, mut behind, mut edges) = (0, 0, 0, 0);
        for portable in [false, true] {
            let mut queue = LookQueue {
                portable,
                ..LookQueue::default()
            };
            for (theta, d, tape) in [
                (-80.0, 5.0, None),
                (0.0, 10.0, Some((20.0, 40.0))),
                (50.0, 25.0, Some((0.0, 1e9))),
                (90.0, 40.0, None),
            ] {
                let shape = Instrument::kflex().shape(theta, d).expect("shape");
                raster.prepare(&camera, &shape);
                // every ray a pixel of its own, and every four rays an edge's pixel
                let mut patches: Vec<(u32, [f32; 3])> = Vec::new();
                let mut want: Vec<(usize, [f32; 3])> = Vec::new();
                let (mut rays, mut edge) = (0, 0);
                raster.tiles(
                    &camera,
                    Roi::whole(k.width, k.height),
                    |scene, _, tile, bodies| {
                        let [x0, y0, x1, y1] = tile;
                        for (x, y) in (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))) {
                            // off the pixel centre, as an edge's rays are
                            let (u, v) = (f64::from(x) + 0.375, f64::from(y) + 0.625);
                            let (Some(hit), d) = scene.first_hit(&camera, bodies, u, v) else {
                                continue;
                            };
                            let c = surface_colour(&scene.bodies, &hit, &d, tape, &env);
                            if under_tape(&hit, tape) {
                                taped += 1;
                            } else {
                                steel += 1;
                                // the mirror ray points back past the camera
                                let n = hit.normal;
                                behind += usize::from(d.z - n.z * 2.0 * n.dot(&d) < 0.05);
                            }
                            let p = patches.len();
                            patches.push((0, [f32::NAN; 3]));
                            want.push((p, c));
                            queue.push(
                                &scene.bodies,
                                &hit,
                                &d,
                                tape,
                                (p as u32, false),
                                &env,
                                &mut patches,
                            );
                            if rays % 4 == 0 {
                                edge = patches.len();
                                patches.push((1, [0.0; 3]));
                                want.push((edge, [0.0; 3]));
                            }
                            let sum =
                                &mut want.iter_mut().rev().find(|w| w.0 == edge).expect("edge").1;
                            (0..3).for_each(|ch| sum[ch] += 0.25 * c[ch]);
                            queue.push(
                                &scene.bodies,
                                &hit,
                                &d,
                                tape,
                                (edge as u32, true),
                                &env,
                                &mut patches,
                            );
                            rays += 1;
                        }
                    },
                );
                queue.flush(&env, &mut patches);
                assert_eq!(patches.len(), want.len());
                for (p, c) in &want {
                    let (kind, got) = patches[*p];
                    assert_eq!(
                        bits(got),
                        bits(*c),
                        "portable {portable}, θ = {theta}, d = {d}, patch {p} (edge: {kind})"
                    );
                    edges += kind;
                }
            }
        }
        assert!(
            steel > 1000 && taped > 1000 && behind > 0 && edges > 1000,
            "{steel} {taped} {behind} {edges}"
        );
    }
}
