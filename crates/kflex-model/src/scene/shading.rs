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

/// What the steel reflects: the tissue in front of the camera (the
/// background image, full frame, linear RGB), and its mean colour.
pub(super) struct Surroundings<'a> {
    pub(super) camera: &'a Camera,
    pub(super) image: &'a [f32],
    pub(super) mean: [f32; 3],
}

impl Surroundings<'_> {
    /// The tissue seen along the reflected ray `r` (camera frame): where
    /// it points ahead, the background pixel it would project to (clamped to
    /// the frame); where it points back past the camera, the dark overtube
    /// and shadowed tissue around it. The pixel is named, not read (see [`Look`]).
    fn along(&self, r: &Vector3<f64>) -> Seen {
        if r.z < 0.05 {
            return Seen::Colour(self.mean.map(|c| 0.3 * c));
        }
        let k = &self.camera.intrinsics;
        let [xd, yd] = self.camera.lens.distort(r.x / r.z, r.y / r.z);
        self.seen(r.z, k.fx * xd + k.cx, k.fy * yd + k.cy)
    }

    /// [`Surroundings::along`] from the reflected ray's depth `z` and the
    /// pixel position `(u, v)` it projects to (worked out only where `z` is
    /// ahead).
    #[inline]
    fn seen(&self, z: f64, u: f64, v: f64) -> Seen {
        if z < 0.05 {
            return Seen::Colour(self.mean.map(|c| 0.3 * c));
        }
        let k = &self.camera.intrinsics;
        let u = u.clamp(0.0, f64::from(k.width) - 1.0) as usize;
        let v = v.clamp(0.0, f64::from(k.height) - 1.0) as usize;
        Seen::At(3 * (v * k.width as usize + u))
    }

    /// The colour at `i` of the background (its mean where outside).
    #[inline]
    fn at(&self, i: usize) -> [f32; 3] {
        match self.image.get(i..i + 3) {
            Some(p) => [p[0], p[1], p[2]],
            None => self.mean,
        }
    }
}

/// What the steel reflects at a point: a background pixel (the index of
/// its red value) or a colour.
#[derive(Debug, Clone, Copy)]
pub(super) enum Seen {
    At(usize),
    Colour([f32; 3]),
}

/// A surface's colour, or all of it but what the steel reflects: the
/// reflected pixel, in a background image too large for the cache, is read
/// after a whole frame's looks are made ([`Look::colour`]), in a loop of
/// independent reads the processor overlaps.
#[derive(Debug, Clone, Copy)]
pub(super) enum Look {
    Done([f32; 3]),
    Steel {
        diffuse: f64,
        reflected: f64,
        highlight: f64,
        seen: Seen,
    },
}

impl Look {
    /// The colour, reading the reflected pixel from `env`.
    #[inline]
    pub(super) fn colour(&self, env: &Surroundings<'_>) -> [f32; 3] {
        match *self {
            Look::Done(c) => c,
            Look::Steel {
                diffuse,
                reflected,
                highlight,
                seen,
            } => {
                let seen = match seen {
                    Seen::At(i) => env.at(i),
                    Seen::Colour(c) => c,
                };
                std::array::from_fn(|k| {
                    (f64::from(METAL[k]) * diffuse + f64::from(seen[k]) * reflected + highlight)
                        as f32
                })
            }
        }
    }
}

/// Whether the surface at `hit` lies under the tape band `tape` (arc lengths).
pub(super) fn under_tape(hit: &SurfaceHit, tape: Option<(f32, f32)>) -> bool {
    let arc = hit.arc_mm as f32;
    tape.is_some_and(|(lo, hi)| arc >= lo && arc <= hi)
}

/// The look of the surface at `hit`, seen along unit `d`: tape where
/// [`under_tape`], else steel; `env` is what the steel reflects. Frames
/// make their looks by [`SteelLooks`]; this one-at-a-time form is the
/// reference its test holds them to.
#[cfg(test)]
fn surface_look(
    bodies: &[CameraBody],
    hit: &SurfaceHit,
    d: &Vector3<f64>,
    tape: Option<(f32, f32)>,
    env: &Surroundings<'_>,
) -> Look {
    if under_tape(hit, tape) {
        return tape_look(hit, d);
    }
    let (shadow, gloss) = steel_finish(bodies, hit);
    steel_look(d, &hit.normal, hit.t, shadow, gloss, env)
}

/// Steel's look where a ray along unit `d` meets it at distance `t` (mm),
/// outward normal `n`, with `shadow` and `gloss` ([`steel_finish`]).
fn steel_look(
    d: &Vector3<f64>,
    n: &Vector3<f64>,
    t: f64,
    shadow: f64,
    gloss: f64,
    env: &Surroundings<'_>,
) -> Look {
    let cos = (-n.dot(d)).clamp(0.0, 1.0);
    let light = INSTRUMENT_LIGHT * falloff(t);
    let fresnel = STEEL_F0 + (1.0 - STEEL_F0) * (1.0 - cos).powi(5);
    // satin steel scatters some light back even at grazing incidence
    let diffuse = (0.28 + 0.42 * cos) * light * shadow;
    let mirror = d - n * (2.0 * d.dot(n));
    let seen = env.along(&mirror);
    // the tissue it reflects is lit about as the steel is (no brighter than nominal)
    let reflected = 0.22 * fresnel * shadow * gloss * falloff(t).min(1.0);
    let highlight = (0.9 * cos.powi(80) + 0.2 * cos.powi(10)) * light * shadow * gloss;
    Look::Steel {
        diffuse,
        reflected,
        highlight,
        seen,
    }
}

/// The tape's look at `hit` seen along unit `d`: matte, Lambert and a faint sheen.
fn tape_look(hit: &SurfaceHit, d: &Vector3<f64>) -> Look {
    let cos = (-hit.normal.dot(d)).clamp(0.0, 1.0);
    let light = INSTRUMENT_LIGHT * falloff(hit.t);
    let diffuse = (0.15 + 0.85 * cos) * light;
    let sheen = 0.04 * cos.powi(16) * light;
    Look::Done(TAPE.map(|c| (f64::from(c) * diffuse + sheen) as f32))
}

/// The steel's finish at `hit`: the shadow on it (the backbone, seen
/// through the gaps between discs, sits in their shadow) and its gloss
/// (machined disc faces are duller than the polished sides).
fn steel_finish(bodies: &[CameraBody], hit: &SurfaceHit) -> (f64, f64) {
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

/// How many looks [`LookQueue`] holds before it makes them.
const QUEUE: usize = 64;

/// A frame's looks, queued while the tiles are walked and made a batch at a
/// time into the colours of the pixels they shade (a kept batch in the
/// first cache level, not a frame's worth of looks in memory).
///
/// Steel's looks are made four to an instruction where the processor has
/// AVX2: the operations of [`steel_look`] in its order (no fused
/// multiply-add, the powers as the compiler expands `powi`: squarings, the
/// set bits' factors multiplied from the lowest), so the same bits (a test
/// holds them equal). Then the queue's looks, in the order they came, go
/// into their pixels: an inner pixel takes its look's colour, an edge's
/// pixel adds a quarter of each of its four rays' (from black, in their
/// order). The reflected pixels are read in that loop, a batch of
/// independent reads the processor overlaps.
#[derive(Debug, Clone)]
pub(super) struct LookQueue {
    /// Steel's inputs, a field to a row: ray (x, y, z), normal (x, y, z),
    /// distance, shadow, gloss; one lane a look.
    rows: [[f64; QUEUE]; 9],
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
    /// Makes steel's looks one at a time even where the processor has AVX2
    /// (the tests hold both ways to the same bits).
    portable: bool,
    /// The steel lanes' colours, once made, and their terms on the way:
    /// diffuse, reflected, highlight, and the reflected ray's depth and
    /// pixel (then the colour it reflects).
    colours: [[f32; 3]; QUEUE],
    out: [[f64; QUEUE]; 6],
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
            colours: [[0.0; 3]; QUEUE],
            out: [[0.0; QUEUE]; 6],
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
        if under_tape(hit, tape) {
            let Look::Done(c) = tape_look(hit, d) else {
                return;
            };
            self.push_colour(c, (patch, edge), env, patches);
            return;
        }
        let (shadow, gloss) = steel_finish(bodies, hit);
        let n = &hit.normal;
        let q = self.steel;
        for (row, v) in self
            .rows
            .iter_mut()
            .zip([d.x, d.y, d.z, n.x, n.y, n.z, hit.t, shadow, gloss])
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

    /// Makes the queued looks and puts them into their pixels' colours in
    /// `patches`; the queue is empty after.
    pub(super) fn flush(&mut self, env: &Surroundings<'_>, patches: &mut [(u32, [f32; 3])]) {
        self.make(env);
        for i in 0..self.len {
            let c = match self.colours.get(self.lane[i] as usize) {
                Some(&c) => c,
                None => self.done[i],
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
        #[cfg(target_arch = "x86_64")]
        if !self.portable && std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the processor has AVX2, checked just above.
            unsafe { self.make_avx2(env) };
            return;
        }
        self.make_portable(env);
    }

    /// One look at a time ([`steel_look`]).
    fn make_portable(&mut self, env: &Surroundings<'_>) {
        let r = &self.rows;
        for q in 0..self.steel {
            let d = Vector3::new(r[0][q], r[1][q], r[2][q]);
            let n = Vector3::new(r[3][q], r[4][q], r[5][q]);
            self.colours[q] = steel_look(&d, &n, r[6][q], r[7][q], r[8][q], env).colour(env);
        }
    }

    /// [`LookQueue::make_portable`] four looks at a time in AVX2; the
    /// reflected pixel's clamp and index stay scalar, as
    /// [`Surroundings::along`] makes them. The last block's unused lanes
    /// hold an earlier batch's values or zeros, computed and dropped.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn make_avx2(&mut self, env: &Surroundings<'_>) {
        use std::arch::x86_64::{
            _CMP_GT_OQ, _CMP_LT_OQ, _mm_storeu_ps, _mm256_add_pd as add, _mm256_blendv_pd,
            _mm256_cmp_pd, _mm256_cvtpd_ps, _mm256_div_pd as div, _mm256_loadu_pd, _mm256_max_pd,
            _mm256_min_pd, _mm256_mul_pd as mul, _mm256_set1_pd as v, _mm256_sqrt_pd,
            _mm256_storeu_pd, _mm256_sub_pd as sub, _mm256_xor_pd,
        };
        // (closures here would not inherit AVX2 and stay out of line)
        macro_rules! sq {
            ($x:expr) => {{
                let x = $x;
                mul(x, x)
            }};
        }
        let k = &env.camera.intrinsics;
        let (fx, cx, fy, cy) = (v(k.fx), v(k.cx), v(k.fy), v(k.cy));
        let four_division = v(4.0 * env.camera.lens.division);
        let (zero, one, two) = (v(0.0), v(1.0), v(2.0));
        for b in (0..self.steel).step_by(4) {
            let r = &self.rows;
            macro_rules! row {
                // SAFETY: `b + 4 <= QUEUE` (a multiple of four), so the row holds four values from `b`.
                ($i:expr) => {
                    unsafe { _mm256_loadu_pd(r[$i][b..b + 4].as_ptr()) }
                };
            }
            let (dx, dy, dz, nx, ny, nz) = (row!(0), row!(1), row!(2), row!(3), row!(4), row!(5));
            let (t, shadow, gloss) = (row!(6), row!(7), row!(8));
            // falloff(t): (30 / max(t, 1))², at most 2.5
            let fall = _mm256_min_pd(sq!(div(v(LIGHT_MM), _mm256_max_pd(t, one))), v(2.5));
            let nd = add(add(mul(nx, dx), mul(ny, dy)), mul(nz, dz));
            // clamp(−n·d, 0, 1), NaN kept as `clamp` keeps it
            let c = _mm256_xor_pd(nd, v(-0.0));
            let c = _mm256_blendv_pd(c, zero, _mm256_cmp_pd::<_CMP_LT_OQ>(c, zero));
            let cos = _mm256_blendv_pd(c, one, _mm256_cmp_pd::<_CMP_GT_OQ>(c, one));
            let light = mul(v(INSTRUMENT_LIGHT), fall);
            // (1 − cos)⁵ = x · x⁴
            let x = sub(one, cos);
            let fresnel = add(v(STEEL_F0), mul(v(1.0 - STEEL_F0), mul(x, sq!(sq!(x)))));
            let diffuse = mul(mul(add(v(0.28), mul(v(0.42), cos)), light), shadow);
            // d − n (2 d·n)
            let twice = mul(two, add(add(mul(dx, nx), mul(dy, ny)), mul(dz, nz)));
            let (rx, ry, rz) = (
                sub(dx, mul(nx, twice)),
                sub(dy, mul(ny, twice)),
                sub(dz, mul(nz, twice)),
            );
            let reflected = mul(
                mul(mul(mul(v(0.22), fresnel), shadow), gloss),
                _mm256_min_pd(fall, one),
            );
            // cos⁸⁰ = cos¹⁶ · cos⁶⁴, cos¹⁰ = cos² · cos⁸
            let c2 = sq!(cos);
            let c8 = sq!(sq!(c2));
            let c16 = sq!(c8);
            let c64 = sq!(sq!(c16));
            let shine = add(mul(v(0.9), mul(c16, c64)), mul(v(0.2), mul(c2, c8)));
            let highlight = mul(mul(mul(shine, light), shadow), gloss);
            // the lens (Lens::distort of the pinhole direction), then the pixel
            let (xu, yu) = (div(rx, rz), div(ry, rz));
            let ru2 = add(mul(xu, xu), mul(yu, yu));
            let root = _mm256_sqrt_pd(_mm256_max_pd(sub(one, mul(four_division, ru2)), zero));
            let s = div(two, add(one, root));
            let (pu, pv) = (add(mul(fx, mul(xu, s)), cx), add(mul(fy, mul(yu, s)), cy));
            for (o, x) in self
                .out
                .iter_mut()
                .zip([diffuse, reflected, highlight, rz, pu, pv])
            {
                // SAFETY: as the loads: the row holds four values from `b`.
                unsafe { _mm256_storeu_pd(o[b..b + 4].as_mut_ptr(), x) };
            }
        }
        // the reflected pixels after the arithmetic, so that the blocks'
        // divisions and square roots overlap
        let [diffuse, reflected, highlight, rz, pu, pv] = &mut self.out;
        for q in 0..self.steel {
            let seen = match env.seen(rz[q], pu[q], pv[q]) {
                Seen::At(i) => env.at(i),
                Seen::Colour(c) => c,
            };
            // (the depth and pixel are read: their rows take the colour)
            (rz[q], pu[q], pv[q]) = (f64::from(seen[0]), f64::from(seen[1]), f64::from(seen[2]));
        }
        // Look::colour: metal · diffuse + seen · reflected + highlight
        let seen = [&*rz, &*pu, &*pv];
        for b in (0..self.steel).step_by(4) {
            // SAFETY: `b + 4 <= QUEUE`, so every row holds four values from `b`.
            let at = |row: &[f64; QUEUE]| unsafe { _mm256_loadu_pd(row[b..b + 4].as_ptr()) };
            let (d, r, h) = (at(diffuse), at(reflected), at(highlight));
            let mut c = [[0.0f32; 4]; 3];
            for (ch, out) in c.iter_mut().enumerate() {
                let x = add(
                    add(mul(v(f64::from(METAL[ch])), d), mul(at(seen[ch]), r)),
                    h,
                );
                // SAFETY: `out` holds four values.
                unsafe { _mm_storeu_ps(out.as_mut_ptr(), _mm256_cvtpd_ps(x)) };
            }
            for (q, colour) in self.colours[b..b + 4].iter_mut().enumerate() {
                *colour = [c[0][q], c[1][q], c[2][q]];
            }
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

    /// The queued looks (AVX2 where the processor has it, and the portable
    /// copy) give, pixel for pixel, the bits of [`surface_look`]'s colours:
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
                            let look = surface_look(&scene.bodies, &hit, &d, tape, &env);
                            match look {
                                Look::Done(_) => taped += 1,
                                Look::Steel { seen, .. } => {
                                    steel += 1;
                                    behind += usize::from(matches!(seen, Seen::Colour(_)));
                                }
                            }
                            let c = look.colour(&env);
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
