//! Ray caster: binary silhouettes of the instrument and the surface point
//! behind each pixel, for any camera lens and any window of the image.

use crate::camera::Camera;
use crate::error::{ModelError, Result};
use crate::instrument::{Ends, InstrumentShape, Part};
use crate::mask::Mask;
use crate::range::Bounds;
use crate::roi::Roi;
use nalgebra::{Point3, Vector3};

/// Side of a coarse tile, px: each is culled against every body.
const COARSE: u32 = 32;

/// The most bodies a shape may have: a tile names its candidates in `u16`.
pub const MAX_BODIES: usize = u16::MAX as usize;
/// Side of a fine tile, px: each is culled against its coarse tile's bodies.
const FINE: u32 = 8;

/// Reusable ray caster.
///
/// A pixel is instrument where the ray through its centre (bent by the
/// camera's [`Lens`](crate::Lens)) meets a body of the shape: exact
/// closed-form hits with cylinders, their flat end discs and the end spheres
/// of capsules, so silhouettes are exact at any size and any pose, with no
/// dilation and no polygon facets. Rays are cast only where they can hit:
/// the image is cut into 32 px tiles, each culled against every body by the
/// cone its rays span, and 8 px tiles inside them against the bodies left.
/// A window of the image ([`Rasterizer::silhouette_window`]) costs its own
/// area and gives exactly the pixels of the full image's crop. No allocation
/// per frame once the [`Rasterizer`]'s buffers have grown.
#[derive(Debug, Default, Clone)]
pub struct Rasterizer {
    scene: Scene,
    optics: Optics,
    coarse: Vec<u16>,
    /// The last walk of [`Rasterizer::tiles`]: each fine tile that has
    /// candidates, its corner and its candidates' range in `walked_bodies`,
    /// in the walk's order; good for the prepared shape, seen by the camera
    /// and over the window of `walked_over`.
    walked: Vec<([u32; 2], std::ops::Range<usize>)>,
    walked_bodies: Vec<u16>,
    walked_over: Option<(Camera, Roi)>,
}

/// What depends on the camera only, kept while it stays: each pixel's unit
/// ray over a window, and each tile's cone (built as tiles are first met).
#[derive(Debug, Clone)]
pub(crate) struct Optics {
    camera: Option<Camera>,
    window: Roi,
    rays: Vec<[f32; 3]>,
    /// Cones of the coarse and the fine tiles, row-major over the full image.
    coarse: Vec<Option<Cone>>,
    fine: Vec<Option<Cone>>,
}

/// No window: the tables hold nothing yet.
const NO_WINDOW: Roi = Roi {
    x0: 0,
    y0: 0,
    width: 0,
    height: 0,
};

impl Default for Optics {
    fn default() -> Self {
        Self {
            camera: None,
            window: NO_WINDOW,
            rays: Vec::new(),
            coarse: Vec::new(),
            fine: Vec::new(),
        }
    }
}

impl Optics {
    /// Makes the tables hold `camera`'s rays over `window`.
    fn cover(&mut self, camera: &Camera, window: Roi) {
        let k = &camera.intrinsics;
        if self.camera != Some(*camera) {
            self.camera = Some(*camera);
            self.window = NO_WINDOW;
            self.rays.clear();
            let tiles = |side: u32| (k.width.div_ceil(side) * k.height.div_ceil(side)) as usize;
            self.coarse.clear();
            self.coarse.resize(tiles(COARSE), None);
            self.fine.clear();
            self.fine.resize(tiles(FINE), None);
        }
        if !self.window.holds(&window) || self.rays.is_empty() {
            self.window = window;
            self.rays.clear();
            for y in window.y0..window.y0 + window.height {
                for x in window.x0..window.x0 + window.width {
                    let d = unit_ray(camera, f64::from(x) + 0.5, f64::from(y) + 0.5);
                    self.rays.push([d.x as f32, d.y as f32, d.z as f32]);
                }
            }
        }
    }

    /// The unit ray through the centre of pixel `(x, y)`, which the window held covers.
    #[inline]
    pub(crate) fn ray(&self, x: u32, y: u32) -> Vector3<f64> {
        let w = &self.window;
        let r = self.rays[((y - w.y0) * w.width + (x - w.x0)) as usize];
        Vector3::new(f64::from(r[0]), f64::from(r[1]), f64::from(r[2]))
    }

    /// The unit rays (in `f32`) through the centres of the pixels `x0..x1`
    /// of row `y`, which the window held covers.
    #[inline]
    fn row(&self, x0: u32, x1: u32, y: u32) -> &[[f32; 3]] {
        let w = &self.window;
        let start = ((y - w.y0) * w.width + (x0 - w.x0)) as usize;
        &self.rays[start..start + (x1 - x0) as usize]
    }

    /// The cone of the tile of side `side` at `(tx, ty)` (tile coordinates).
    fn cone(&mut self, camera: &Camera, side: u32, tx: u32, ty: u32) -> Cone {
        let cols = camera.intrinsics.width.div_ceil(side);
        let slots = if side == COARSE {
            &mut self.coarse
        } else {
            &mut self.fine
        };
        let slot = &mut slots[(ty * cols + tx) as usize];
        *slot.get_or_insert_with(|| {
            Cone::of(
                camera,
                [tx * side, ty * side, (tx + 1) * side, (ty + 1) * side],
            )
        })
    }
}

/// The shape's bodies in the camera frame.
#[derive(Debug, Default, Clone)]
pub(crate) struct Scene {
    pub(crate) bodies: Vec<CameraBody>,
}

/// Where a ray meets a body first.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SurfaceHit {
    /// Distance along the unit ray, mm.
    pub(crate) t: f64,
    /// Index of the body in the shape.
    pub(crate) body: usize,
    /// Outward unit normal, camera frame.
    pub(crate) normal: Vector3<f64>,
    /// Arc length along the instrument, mm.
    pub(crate) arc_mm: f64,
    /// Whether the ray meets an end (a flat disc or an end sphere), not the side.
    pub(crate) on_end: bool,
}

impl Rasterizer {
    /// A rasterizer with empty buffers.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// Draws the silhouette of `shape` seen by `camera` into `mask` (which must have the
    /// camera's size); pixels already set stay set.
    ///
    /// # Errors
    /// [`ModelError::ImageSize`] when `mask` is not the camera's
    /// `width × height`; as [`crate::Camera::validate`] for a bad camera;
    /// [`ModelError::OutOfRange`] for a shape of more than [`MAX_BODIES`]
    /// bodies. Nothing is drawn then.
    pub fn silhouette(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        mask: &mut Mask,
    ) -> Result<()> {
        let k = &camera.intrinsics;
        let full = Roi::whole(k.width, k.height);
        self.silhouette_window(camera, shape, full, mask)
    }

    /// The silhouette of `shape` inside `window` of `camera`'s image, into
    /// `mask` (of the window's size): exactly the window's crop of
    /// [`Rasterizer::silhouette`]'s image, at a cost proportional to the
    /// window's area. Pixels already set stay set.
    ///
    /// # Errors
    /// As [`Roi::check_within`] for a window outside the image;
    /// [`ModelError::ImageSize`] when `mask` is not the window's size; as
    /// [`crate::Camera::validate`] for a bad camera;
    /// [`ModelError::OutOfRange`] for a shape of more than [`MAX_BODIES`]
    /// bodies. Nothing is drawn then.
    pub fn silhouette_window(
        &mut self,
        camera: &Camera,
        shape: &InstrumentShape,
        window: Roi,
        mask: &mut Mask,
    ) -> Result<()> {
        camera.validate()?;
        Self::check_shape(shape)?;
        let k = &camera.intrinsics;
        window.check_within(k.width, k.height)?;
        if (mask.width(), mask.height()) != (window.width, window.height) {
            return Err(ModelError::ImageSize {
                what: "mask for this window",
                width: window.width,
                height: window.height,
                expected: window.area() as usize,
                got: mask.data().len(),
            });
        }
        self.prepare(camera, shape);
        let w = window.width as usize;
        self.tiles(
            camera,
            window,
            |scene, optics, [x0, y0, x1, y1], candidates| {
                for y in y0..y1 {
                    let row = (y - window.y0) as usize * w;
                    for x in x0..x1 {
                        let (u, v) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                        if scene.any_hit(candidates, u, v, || optics.ray(x, y)) {
                            mask.set_index(row + (x - window.x0) as usize);
                        }
                    }
                }
            },
        );
        Ok(())
    }

    /// Refuses a shape with more bodies than a tile's candidate list can
    /// name ([`MAX_BODIES`]; the instrument's own shapes have a few dozen).
    pub(crate) fn check_shape(shape: &InstrumentShape) -> Result<()> {
        Bounds::closed(0.0, MAX_BODIES as f64)
            .check("shape.bodies (count)", shape.bodies.len() as f64)?;
        Ok(())
    }

    /// Puts `shape`'s bodies into `camera`'s frame.
    pub(crate) fn prepare(&mut self, camera: &Camera, shape: &InstrumentShape) {
        self.walked_over = None;
        self.scene.bodies.clear();
        self.scene.bodies.extend(shape.bodies.iter().map(|b| {
            let to = |p: [f64; 3]| (camera.camera_from_overtube * Point3::from(p)).coords;
            let mut body = CameraBody::new(
                to(b.a_mm),
                to(b.b_mm),
                b.radius_mm,
                b.ends,
                b.part,
                b.arc_mm,
            );
            body.screen = body.pixel_box(camera);
            body
        }));
    }

    /// Calls `f` for every fine tile of `window` (pixel box `[x0, y0, x1,
    /// y1)` in the full image's coordinates) that some body may cover, with
    /// the indices of those bodies. Tiles are aligned to the full image, so
    /// the culling does not depend on the window: a window inside the last
    /// one walked for the same shape and camera (a frame's shading after its
    /// centre rays) takes that walk's tiles, clipped to it, in their order.
    pub(crate) fn tiles(
        &mut self,
        camera: &Camera,
        window: Roi,
        mut f: impl FnMut(&Scene, &Optics, [u32; 4], &[u16]),
    ) {
        self.optics.cover(camera, window);
        if !self
            .walked_over
            .is_some_and(|(c, over)| c == *camera && over.holds(&window))
        {
            self.walk(camera, window);
        }
        let (wx0, wy0) = (window.x0, window.y0);
        let (wx1, wy1) = (wx0 + window.width, wy0 + window.height);
        for ([fx, fy], bodies) in &self.walked {
            let tile = [
                (*fx).max(wx0),
                (*fy).max(wy0),
                (fx + FINE).min(wx1),
                (fy + FINE).min(wy1),
            ];
            if tile[0] < tile[2] && tile[1] < tile[3] {
                let bodies = &self.walked_bodies[bodies.clone()];
                f(&self.scene, &self.optics, tile, bodies);
            }
        }
    }

    /// Culls the fine tiles of `window` (the optics covering it) into
    /// `walked`: each coarse tile against every body, then its fine tiles
    /// against the bodies left, nearest first.
    fn walk(&mut self, camera: &Camera, window: Roi) {
        self.walked.clear();
        self.walked_bodies.clear();
        let (wx0, wy0) = (window.x0, window.y0);
        let (wx1, wy1) = (wx0 + window.width, wy0 + window.height);
        let all = self.scene.bodies.len().min(MAX_BODIES) as u16;
        let mut cy = wy0 / COARSE * COARSE;
        while cy < wy1 {
            let mut cx = wx0 / COARSE * COARSE;
            while cx < wx1 {
                let rect = [cx, cy, cx + COARSE, cy + COARSE].map(f64::from);
                let cone = self.optics.cone(camera, COARSE, cx / COARSE, cy / COARSE);
                self.coarse.clear();
                self.coarse.extend((0..all).filter(|&i| {
                    let body = &self.scene.bodies[usize::from(i)];
                    body.box_meets(rect) && body.may_meet(&cone)
                }));
                // nearest first: a ray stops looking once its hit is nearer
                // than the next body can be (the fine lists keep the order)
                let bodies = &self.scene.bodies;
                self.coarse.sort_by(|&i, &j| {
                    bodies[usize::from(i)]
                        .near
                        .total_cmp(&bodies[usize::from(j)].near)
                });
                if !self.coarse.is_empty() {
                    let (ex, ey) = ((cx + COARSE).min(wx1), (cy + COARSE).min(wy1));
                    let mut fy = cy.max(wy0) / FINE * FINE;
                    while fy < ey {
                        let mut fx = cx.max(wx0) / FINE * FINE;
                        while fx < ex {
                            let cone = self.optics.cone(camera, FINE, fx / FINE, fy / FINE);
                            let rect = [fx, fy, fx + FINE, fy + FINE].map(f64::from);
                            let from = self.walked_bodies.len();
                            self.walked_bodies
                                .extend(self.coarse.iter().copied().filter(|&i| {
                                    let body = &self.scene.bodies[usize::from(i)];
                                    body.box_meets(rect) && body.may_meet(&cone)
                                }));
                            if self.walked_bodies.len() > from {
                                self.walked.push(([fx, fy], from..self.walked_bodies.len()));
                            }
                            fx += FINE;
                        }
                        fy += FINE;
                    }
                }
                cx += COARSE;
            }
            cy += COARSE;
        }
        self.walked_over = Some((*camera, window));
    }
}

impl Rasterizer {
    /// Calls `f(x, y, hit)` for every pixel of `window` whose centre ray
    /// meets the prepared shape, with where it meets it first.
    ///
    /// A fine tile's rays are cast body by body (each ray as
    /// [`Scene::first_hit_along`] casts it, to the same hit): the rays of a
    /// tile are independent, so the processor overlaps their divisions and
    /// square roots.
    pub(crate) fn centre_hits(
        &mut self,
        camera: &Camera,
        window: Roi,
        mut f: impl FnMut(u32, u32, SurfaceHit),
    ) {
        let mut lanes = Lanes::default();
        let wide = Lanes::wide();
        self.tiles(
            camera,
            window,
            |scene, optics, [x0, y0, x1, y1], candidates| {
                lanes.load(optics, [x0, y0, x1, y1]);
                lanes.cast(&scene.bodies, candidates, wide);
                let mut k = 0;
                for y in y0..y1 {
                    for x in x0..x1 {
                        if let Some(hit) = lanes.hit(scene, k) {
                            f(x, y, hit);
                        }
                        k += 1;
                    }
                }
            },
        );
    }
}

/// Rays through any pixel positions, cast a batch at a time as a fine
/// tile's centre rays are ([`Rasterizer::centre_hits`]): to the hits of
/// [`Scene::first_hit`], bit for bit.
#[derive(Debug, Clone)]
pub(crate) struct RayBatch {
    lanes: Lanes,
    wide: bool,
}

impl Default for RayBatch {
    fn default() -> Self {
        Self {
            lanes: Lanes::default(),
            wide: Lanes::wide(),
        }
    }
}

impl RayBatch {
    /// Casts the ray through each pixel position of `points` against the
    /// bodies `candidates` (nearest first, as a tile lists them) and calls
    /// `f(k, hit, d)` for each, in order: `hit` where the ray `d` meets one
    /// first ([`Scene::first_hit`]'s).
    pub(crate) fn first_hits(
        &mut self,
        camera: &Camera,
        scene: &Scene,
        candidates: &[u16],
        points: &[(f64, f64)],
        mut f: impl FnMut(usize, Option<SurfaceHit>, &Vector3<f64>),
    ) {
        let lanes = &mut self.lanes;
        for (c, chunk) in points.chunks(TILE_RAYS).enumerate() {
            lanes.load_points(camera, chunk);
            lanes.cast(&scene.bodies, candidates, self.wide);
            for k in 0..chunk.len() {
                let d = Vector3::new(lanes.dx[k], lanes.dy[k], lanes.dz[k]);
                f(c * TILE_RAYS + k, lanes.hit(scene, k), &d);
            }
        }
    }
}

/// A fine tile's rays as a structure of arrays, one lane a ray, and each
/// ray's nearest hit so far: distance `t` (infinite for none), axial
/// parameter `u`, surface `s` (0 side, 1 end A, 2 end B) and body `i`.
/// Every lane is cast against a whole body at once, without branches, so
/// the compiler runs four rays in each vector instruction; the lanes past a
/// partial tile's rays are never live.
///
/// The arithmetic is [`CameraBody::hit`]'s, operation for operation (no
/// fused multiply-add), and a hit replaces the ray's nearest only when
/// strictly nearer, surface by surface in `hit`'s order: the same bits as
/// [`Scene::first_hit_along`] (a test holds them equal). Where `hit` bails
/// out on a negated test (`qa <= 1e-18`, `|d·a| <= 1e-12`), the lanes ask
/// the positive one: they differ only for NaN, which no hit survives either
/// way, and a lane's distance is never NaN.
#[derive(Debug, Clone)]
struct Lanes {
    dx: [f64; TILE_RAYS],
    dy: [f64; TILE_RAYS],
    dz: [f64; TILE_RAYS],
    pu: [f64; TILE_RAYS],
    pv: [f64; TILE_RAYS],
    t: [f64; TILE_RAYS],
    u: [f64; TILE_RAYS],
    s: [f64; TILE_RAYS],
    i: [f64; TILE_RAYS],
}

impl Default for Lanes {
    fn default() -> Self {
        Self {
            dx: [0.0; TILE_RAYS],
            dy: [0.0; TILE_RAYS],
            dz: [1.0; TILE_RAYS],
            pu: [f64::NAN; TILE_RAYS],
            pv: [f64::NAN; TILE_RAYS],
            t: [f64::INFINITY; TILE_RAYS],
            u: [0.0; TILE_RAYS],
            s: [0.0; TILE_RAYS],
            i: [0.0; TILE_RAYS],
        }
    }
}

impl Lanes {
    /// Whether this processor runs the AVX2 copy of [`Lanes::cast`].
    fn wide() -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            std::arch::is_x86_feature_detected!("avx2")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    }

    /// The rays of the tile `[x0, y0, x1, y1)`, row by row, with no hit yet;
    /// the lanes past them hold no pixel (NaN), so no body's box holds them,
    /// and a hit nearer than every body (−∞), so they never hold a tile's
    /// bodies back from the nearest-first stop.
    fn load(&mut self, optics: &Optics, [x0, y0, x1, y1]: [u32; 4]) {
        let mut n = 0;
        for y in y0..y1 {
            let v = f64::from(y) + 0.5;
            for (x, r) in (x0..x1).zip(optics.row(x0, x1, y)) {
                if n == TILE_RAYS {
                    break;
                }
                (self.dx[n], self.dy[n], self.dz[n]) = r.map(f64::from).into();
                (self.pu[n], self.pv[n]) = (f64::from(x) + 0.5, v);
                n += 1;
            }
        }
        self.pu[n..].fill(f64::NAN);
        self.pv[n..].fill(f64::NAN);
        self.t[..n].fill(f64::INFINITY);
        self.t[n..].fill(f64::NEG_INFINITY);
    }

    /// The rays through the pixel positions `points` (at most
    /// [`TILE_RAYS`]), each as [`unit_ray`] makes it, with no hit yet; the
    /// lanes past them as [`Lanes::load`] leaves its.
    fn load_points(&mut self, camera: &Camera, points: &[(f64, f64)]) {
        let n = points.len().min(TILE_RAYS);
        for (k, &(u, v)) in points.iter().take(n).enumerate() {
            let d = unit_ray(camera, u, v);
            (self.dx[k], self.dy[k], self.dz[k]) = (d.x, d.y, d.z);
            (self.pu[k], self.pv[k]) = (u, v);
        }
        self.pu[n..].fill(f64::NAN);
        self.pv[n..].fill(f64::NAN);
        self.t[..n].fill(f64::INFINITY);
        self.t[n..].fill(f64::NEG_INFINITY);
    }

    /// Lane `k`'s first hit after [`Lanes::cast`], if its ray met a body.
    #[inline]
    fn hit(&self, scene: &Scene, k: usize) -> Option<SurfaceHit> {
        // a miss is +∞, a lane past the rays loaded −∞
        match self.t.get(k) {
            Some(&t) if t.is_finite() => {}
            _ => return None,
        }
        let d = Vector3::new(self.dx[k], self.dy[k], self.dz[k]);
        let s = if self.s[k] == 0.0 {
            Surface::Side
        } else if self.s[k] == 1.0 {
            Surface::EndA
        } else {
            Surface::EndB
        };
        Some(scene.surface_hit(&d, self.t[k], self.u[k], s, self.i[k] as usize))
    }

    /// Casts every lane against the bodies `candidates` (nearest first),
    /// four lanes to an instruction where `wide`.
    fn cast(&mut self, bodies: &[CameraBody], candidates: &[u16], wide: bool) {
        for &i in candidates {
            let Some(body) = bodies.get(usize::from(i)) else {
                continue;
            };
            // a ray whose hit is nearer than the body can be is done with it
            if !self.t.iter().any(|&t| t >= body.near) {
                break;
            }
            let id = f64::from(i);
            #[cfg(target_arch = "x86_64")]
            if wide {
                // SAFETY: `wide` is true only where the processor has AVX2 (`Lanes::wide`).
                unsafe {
                    match (body.len > 1e-9, body.ends) {
                        (true, Ends::Round) => self.body_avx2::<true, false, true>(body, id),
                        (true, Ends::Flat) => self.body_avx2::<true, true, false>(body, id),
                        (false, Ends::Round) => self.body_avx2::<false, false, true>(body, id),
                        (false, Ends::Flat) => {}
                    }
                }
                continue;
            }
            let _ = wide;
            match (body.len > 1e-9, body.ends) {
                (true, Ends::Round) => self.body::<true, false, true>(body, id),
                (true, Ends::Flat) => self.body::<true, true, false>(body, id),
                (false, Ends::Round) => self.body::<false, false, true>(body, id),
                // a flat body of no length is a disc of no thickness
                (false, Ends::Flat) => {}
            }
        }
    }

    /// [`Lanes::body`] four lanes at a time in AVX2: the same operations in
    /// the same order, each comparison with the same answer for NaN (an
    /// ordered one for `<`, `<=`, `>`, `>=`, an unordered one under `!`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn body_avx2<const SIDE: bool, const DISCS: bool, const SPHERES: bool>(
        &mut self,
        body: &CameraBody,
        id: f64,
    ) {
        use std::arch::x86_64::{
            __m256d, _CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NLE_UQ, _CMP_NLT_UQ,
            _mm256_add_pd, _mm256_and_pd, _mm256_andnot_pd, _mm256_blendv_pd, _mm256_cmp_pd,
            _mm256_div_pd, _mm256_loadu_pd, _mm256_movemask_pd, _mm256_mul_pd, _mm256_or_pd,
            _mm256_set1_pd, _mm256_sqrt_pd, _mm256_storeu_pd, _mm256_sub_pd, _mm256_xor_pd,
        };
        let b = body;
        let v = |x: f64| _mm256_set1_pd(x);
        let (add, sub, mul, div) = (_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd, _mm256_div_pd);
        let (and, blend) = (_mm256_and_pd, _mm256_blendv_pd);
        let [s0, s1, s2, s3] = b.screen.map(v);
        let (ax, ay, az) = (v(b.axis.x), v(b.axis.y), v(b.axis.z));
        let (cx, cy, cz) = (v(b.across.x), v(b.across.y), v(b.across.z));
        let (near, across_c, a_axis, len) = (v(b.near), v(b.across_c), v(b.a_axis), v(b.len));
        let r2 = v(b.r * b.r);
        let (zero, one, two, four) = (v(0.0), v(1.0), v(2.0), v(4.0));
        let (nan, sign, id) = (v(f64::NAN), v(-0.0), v(id));
        for k in (0..TILE_RAYS).step_by(4) {
            // SAFETY: `k + 4 <= TILE_RAYS`, the length of every array read and written.
            let at = |a: &[f64; TILE_RAYS]| unsafe { _mm256_loadu_pd(a.as_ptr().add(k)) };
            let (pu, pv, t0) = (at(&self.pu), at(&self.pv), at(&self.t));
            let live = and(
                and(
                    _mm256_cmp_pd::<_CMP_NLT_UQ>(t0, near),
                    and(
                        _mm256_cmp_pd::<_CMP_GE_OQ>(pu, s0),
                        _mm256_cmp_pd::<_CMP_LE_OQ>(pu, s2),
                    ),
                ),
                and(
                    _mm256_cmp_pd::<_CMP_GE_OQ>(pv, s1),
                    _mm256_cmp_pd::<_CMP_LE_OQ>(pv, s3),
                ),
            );
            if _mm256_movemask_pd(live) == 0 {
                continue;
            }
            let (dx, dy, dz) = (at(&self.dx), at(&self.dy), at(&self.dz));
            let (mut t, mut u, mut s, mut hit) = (t0, at(&self.u), at(&self.s), zero);
            let mut keep = |tc: __m256d, uc: __m256d, sc: __m256d| {
                let take = and(
                    live,
                    and(
                        _mm256_cmp_pd::<_CMP_GT_OQ>(tc, zero),
                        _mm256_cmp_pd::<_CMP_LT_OQ>(tc, t),
                    ),
                );
                t = blend(t, tc, take);
                u = blend(u, uc, take);
                s = blend(s, sc, take);
                hit = _mm256_or_pd(hit, take);
            };
            let dot =
                |x: __m256d, y: __m256d, z: __m256d| add(add(mul(dx, x), mul(dy, y)), mul(dz, z));
            if SIDE {
                let da = dot(ax, ay, az);
                let qa = sub(one, mul(da, da));
                let qb = mul(two, dot(cx, cy, cz));
                let disc = sub(mul(qb, qb), mul(mul(four, qa), across_c));
                let tc = div(
                    sub(_mm256_xor_pd(qb, sign), _mm256_sqrt_pd(disc)),
                    mul(two, qa),
                );
                let along = sub(mul(tc, da), a_axis);
                let on = and(
                    and(
                        _mm256_cmp_pd::<_CMP_NLE_UQ>(qa, v(1e-18)),
                        _mm256_cmp_pd::<_CMP_NLT_UQ>(disc, zero),
                    ),
                    and(
                        _mm256_cmp_pd::<_CMP_GE_OQ>(along, zero),
                        _mm256_cmp_pd::<_CMP_LE_OQ>(along, len),
                    ),
                );
                keep(blend(nan, tc, on), div(along, len), zero);
                if DISCS {
                    let flat = _mm256_cmp_pd::<_CMP_NLE_UQ>(_mm256_andnot_pd(sign, da), v(1e-12));
                    for (c, c_axis, sc) in [(&b.a, b.a_axis, 1.0), (&b.b, b.b_axis, 2.0)] {
                        let tc = div(v(c_axis), da);
                        let ex = sub(mul(dx, tc), v(c.x));
                        let ey = sub(mul(dy, tc), v(c.y));
                        let ez = sub(mul(dz, tc), v(c.z));
                        let n2 = add(add(mul(ex, ex), mul(ey, ey)), mul(ez, ez));
                        let on = and(flat, _mm256_cmp_pd::<_CMP_LE_OQ>(n2, r2));
                        keep(blend(nan, tc, on), v(sc - 1.0), v(sc));
                    }
                }
            }
            if SPHERES {
                for (c, kc, sc) in [(&b.a, b.spheres[0], 1.0), (&b.b, b.spheres[1], 2.0)] {
                    let cd = dot(v(c.x), v(c.y), v(c.z));
                    let disc = sub(mul(cd, cd), v(kc));
                    let tc = sub(cd, _mm256_sqrt_pd(disc));
                    let on = _mm256_cmp_pd::<_CMP_GE_OQ>(disc, zero);
                    keep(blend(nan, tc, on), v(sc - 1.0), v(sc));
                }
            }
            let i = blend(at(&self.i), id, hit);
            // SAFETY: as the loads.
            unsafe {
                _mm256_storeu_pd(self.t.as_mut_ptr().add(k), t);
                _mm256_storeu_pd(self.u.as_mut_ptr().add(k), u);
                _mm256_storeu_pd(self.s.as_mut_ptr().add(k), s);
                _mm256_storeu_pd(self.i.as_mut_ptr().add(k), i);
            }
        }
    }

    /// Every lane against `body` (index `id`): its side where `SIDE`, its
    /// flat end discs where `DISCS`, its end spheres where `SPHERES`.
    #[inline(always)]
    fn body<const SIDE: bool, const DISCS: bool, const SPHERES: bool>(
        &mut self,
        body: &CameraBody,
        id: f64,
    ) {
        let b = body;
        let [s0, s1, s2, s3] = b.screen;
        let (ax, ay, az) = (b.axis.x, b.axis.y, b.axis.z);
        let (cx, cy, cz) = (b.across.x, b.across.y, b.across.z);
        let r2 = b.r * b.r;
        for k in 0..TILE_RAYS {
            let (dx, dy, dz) = (self.dx[k], self.dy[k], self.dz[k]);
            let (pu, pv) = (self.pu[k], self.pv[k]);
            let live = (self.t[k] >= b.near) & (pu >= s0) & (pu <= s2) & (pv >= s1) & (pv <= s3);
            let (mut t, mut u, mut s) = (self.t[k], self.u[k], self.s[k]);
            let mut hit = false;
            let mut keep = |tc: f64, uc: f64, sc: f64| {
                let take = live & (tc > 0.0) & (tc < t);
                t = if take { tc } else { t };
                u = if take { uc } else { u };
                s = if take { sc } else { s };
                hit |= take;
            };
            if SIDE {
                let da = dx * ax + dy * ay + dz * az;
                // the side: CameraBody::side
                let qa = 1.0 - da * da;
                let qb = 2.0 * (dx * cx + dy * cy + dz * cz);
                let disc = qb * qb - 4.0 * qa * b.across_c;
                let tc = (-qb - disc.sqrt()) / (2.0 * qa);
                let along = tc * da - b.a_axis;
                let on = (qa > 1e-18) & (disc >= 0.0) & (along >= 0.0) & (along <= b.len);
                keep(if on { tc } else { f64::NAN }, along / b.len, 0.0);
                if DISCS {
                    // the end discs: CameraBody::end_disc
                    for (c, c_axis, sc) in [(&b.a, b.a_axis, 1.0), (&b.b, b.b_axis, 2.0)] {
                        let tc = c_axis / da;
                        let (ex, ey, ez) = (dx * tc - c.x, dy * tc - c.y, dz * tc - c.z);
                        let on = (da.abs() > 1e-12) & (ex * ex + ey * ey + ez * ez <= r2);
                        keep(if on { tc } else { f64::NAN }, sc - 1.0, sc);
                    }
                }
            }
            if SPHERES {
                for (c, kc, sc) in [(&b.a, b.spheres[0], 1.0), (&b.b, b.spheres[1], 2.0)] {
                    let cd = c.x * dx + c.y * dy + c.z * dz;
                    let disc = cd * cd - kc;
                    let tc = cd - disc.sqrt();
                    keep(if disc >= 0.0 { tc } else { f64::NAN }, sc - 1.0, sc);
                }
            }
            self.t[k] = t;
            self.u[k] = u;
            self.s[k] = s;
            self.i[k] = if hit { id } else { self.i[k] };
        }
    }
}

/// Rays in a fine tile.
const TILE_RAYS: usize = (FINE * FINE) as usize;

/// The unit ray through pixel position `(u, v)`, camera frame.
#[inline]
pub(crate) fn unit_ray(camera: &Camera, u: f64, v: f64) -> Vector3<f64> {
    let [x, y, z] = camera.ray_direction(u, v);
    Vector3::new(x, y, z).normalize()
}

/// The point of the segment `a`–`b` nearest the origin.
fn closest_to_origin(a: Vector3<f64>, b: Vector3<f64>) -> Vector3<f64> {
    let e = b - a;
    let ee = e.norm_squared();
    let s = if ee > 1e-18 {
        (-a.dot(&e) / ee).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + e * s
}

/// The cone of rays through a pixel box: its axis and the sine of its half-angle.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Cone {
    axis: Vector3<f64>,
    sin_half: f64,
}

impl Cone {
    /// The cone through the box `[x0, y0, x1, y1)` (pixel edges, full image).
    fn of(camera: &Camera, [x0, y0, x1, y1]: [u32; 4]) -> Cone {
        let (x0, y0, x1, y1) = (f64::from(x0), f64::from(y0), f64::from(x1), f64::from(y1));
        let (xm, ym) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
        let axis = unit_ray(camera, xm, ym);
        // the widest ray of the box is on its rim: corners and mid-edges
        // (the lens bends the rim only slightly over a tile)
        let mut cos = 1.0f64;
        for (u, v) in [
            (x0, y0),
            (x1, y0),
            (x0, y1),
            (x1, y1),
            (xm, y0),
            (xm, y1),
            (x0, ym),
            (x1, ym),
        ] {
            cos = cos.min(axis.dot(&unit_ray(camera, u, v)));
        }
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        Cone {
            axis,
            sin_half: sin * 1.05 + 1e-9,
        }
    }
}

/// A body in the camera frame, ready for rays from the camera centre.
#[derive(Debug, Clone)]
pub(crate) struct CameraBody {
    a: Vector3<f64>,
    b: Vector3<f64>,
    r: f64,
    pub(crate) ends: Ends,
    pub(crate) part: Part,
    arc: [f64; 2],
    /// Unit axis from `a` to `b`, and the length.
    axis: Vector3<f64>,
    len: f64,
    /// `a · axis` and `b · axis`.
    a_axis: f64,
    b_axis: f64,
    /// The part of `−a` across the axis, and its squared length less `r²`.
    across: Vector3<f64>,
    across_c: f64,
    /// `|a|² − r²` and `|b|² − r²`, for the end spheres.
    spheres: [f64; 2],
    /// The farthest distance of any of its points from the camera, bounded.
    far: f64,
    /// Pixel box `[u_min, v_min, u_max, v_max]` that holds its image
    /// (infinite where it reaches the camera's plane).
    screen: [f64; 4],
    /// No ray meets it nearer than this, mm.
    near: f64,
}

/// Which surface of a body a ray meets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Surface {
    Side,
    EndA,
    EndB,
}

impl CameraBody {
    fn new(
        a: Vector3<f64>,
        b: Vector3<f64>,
        r: f64,
        ends: Ends,
        part: Part,
        arc: [f64; 2],
    ) -> Self {
        let ba = b - a;
        let len = ba.norm();
        let axis = if len > 1e-9 { ba / len } else { Vector3::z() };
        let across = -a - axis * (-a).dot(&axis);
        Self {
            a,
            b,
            r,
            ends,
            part,
            arc,
            axis,
            len,
            a_axis: a.dot(&axis),
            b_axis: b.dot(&axis),
            across,
            across_c: across.norm_squared() - r * r,
            spheres: [a.norm_squared() - r * r, b.norm_squared() - r * r],
            far: a.norm().max(b.norm()) + r,
            screen: [
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::INFINITY,
            ],
            near: (closest_to_origin(a, b).norm() - r).max(0.0),
        }
    }

    /// The pixel box of the capsule of its radius (which holds the body):
    /// the union of its end spheres' boxes of pinhole directions, bent by
    /// the lens ([`image_box`]); infinite where a sphere reaches the camera's plane.
    fn pixel_box(&self, camera: &Camera) -> [f64; 4] {
        match pinhole_box(self.a, self.r).zip(pinhole_box(self.b, self.r)) {
            Some((p, q)) => image_box(
                camera,
                [
                    p[0].min(q[0]),
                    p[1].min(q[1]),
                    p[2].max(q[2]),
                    p[3].max(q[3]),
                ],
            ),
            None => [
                f64::NEG_INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::INFINITY,
            ],
        }
    }

    /// Whether its pixel box meets the pixel box `[x0, y0, x1, y1]`.
    #[inline]
    fn box_meets(&self, [x0, y0, x1, y1]: [f64; 4]) -> bool {
        let s = &self.screen;
        s[0] <= x1 && s[2] >= x0 && s[1] <= y1 && s[3] >= y0
    }

    /// Whether its pixel box holds the pixel position `(u, v)`.
    #[inline]
    pub(crate) fn box_holds(&self, u: f64, v: f64) -> bool {
        let s = &self.screen;
        u >= s[0] && u <= s[2] && v >= s[1] && v <= s[3]
    }

    /// Whether a ray inside `cone` may meet the body. A ray `d` within the
    /// cone's half-angle `α` of its axis `c` that meets the body at `q`
    /// passes `q` within `|q| sin α` of the line along `c`; `q` is within
    /// `r` of the axis segment and `|q| ≤ far`. So the segment comes within
    /// `r + far · sin α` of that line, or no ray of the cone meets the body.
    #[inline]
    fn may_meet(&self, cone: &Cone) -> bool {
        let c = &cone.axis;
        // the segment a + s (b − a) across the line: affine in s
        let pa = self.a - c * self.a.dot(c);
        let pb = self.b - c * self.b.dot(c);
        let e = pb - pa;
        let ee = e.norm_squared();
        let s = if ee > 1e-18 {
            (-pa.dot(&e) / ee).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let reach = self.r + self.far * cone.sin_half;
        (pa + e * s).norm_squared() <= reach * reach
    }

    /// The first hit of the ray from the origin along unit `d`: its
    /// distance, the axial parameter in `[0, 1]` and the surface (the
    /// reference of the lanes' cast).
    #[cfg(test)]
    fn hit(&self, d: &Vector3<f64>) -> Option<(f64, f64, Surface)> {
        let mut best: Option<(f64, f64, Surface)> = None;
        let mut keep = |t: f64, u: f64, s: Surface| {
            if t > 0.0 && best.is_none_or(|b| t < b.0) {
                best = Some((t, u, s));
            }
        };
        if self.len > 1e-9 {
            let da = d.dot(&self.axis);
            if let Some((t, u)) = self.side(d, da) {
                keep(t, u, Surface::Side);
            }
            if self.ends == Ends::Flat {
                for (c, u, s) in [(&self.a, 0.0, Surface::EndA), (&self.b, 1.0, Surface::EndB)] {
                    if let Some(t) = self.end_disc(d, da, c) {
                        keep(t, u, s);
                    }
                }
            }
        }
        // a flat body of no length is a disc of no thickness: nothing to hit
        if self.ends == Ends::Round {
            for (c, k, u, s) in [
                (&self.a, self.spheres[0], 0.0, Surface::EndA),
                (&self.b, self.spheres[1], 1.0, Surface::EndB),
            ] {
                let cd = c.dot(d);
                let disc = cd * cd - k;
                if disc >= 0.0 {
                    keep(cd - disc.sqrt(), u, s);
                }
            }
        }
        best
    }

    /// Where the ray along unit `d` (with `da = d · axis`) meets the side:
    /// `|d t − a|² across the axis = r²`, the nearer root, if it lies
    /// between the ends; its distance and axial parameter in `[0, 1]`.
    #[inline]
    fn side(&self, d: &Vector3<f64>, da: f64) -> Option<(f64, f64)> {
        let qa = 1.0 - da * da;
        let qb = 2.0 * d.dot(&self.across);
        let disc = qb * qb - 4.0 * qa * self.across_c;
        if qa <= 1e-18 || disc < 0.0 {
            return None;
        }
        let t = (-qb - disc.sqrt()) / (2.0 * qa);
        let along = t * da - self.a_axis;
        (0.0..=self.len)
            .contains(&along)
            .then(|| (t, along / self.len))
    }

    /// Where the ray along unit `d` meets the flat end disc centred on `c`
    /// (the plane through `c` across the axis), if within the radius.
    #[inline]
    fn end_disc(&self, d: &Vector3<f64>, da: f64, c: &Vector3<f64>) -> Option<f64> {
        if da.abs() <= 1e-12 {
            return None;
        }
        let t = c.dot(&self.axis) / da;
        ((d * t - c).norm_squared() <= self.r * self.r).then_some(t)
    }

    /// Whether the ray from the origin along unit `d` meets the body at all
    /// ([`CameraBody::hit`] without looking for the nearest surface).
    #[inline]
    fn meets(&self, d: &Vector3<f64>) -> bool {
        if self.len > 1e-9 {
            let da = d.dot(&self.axis);
            if self.side(d, da).is_some_and(|(t, _)| t > 0.0) {
                return true;
            }
            if self.ends == Ends::Flat
                && [&self.a, &self.b]
                    .iter()
                    .any(|c| self.end_disc(d, da, c).is_some_and(|t| t > 0.0))
            {
                return true;
            }
        }
        self.ends == Ends::Round
            && [(&self.a, self.spheres[0]), (&self.b, self.spheres[1])]
                .iter()
                .any(|&(c, k)| {
                    let cd = c.dot(d);
                    let disc = cd * cd - k;
                    disc >= 0.0 && cd - disc.sqrt() > 0.0
                })
    }

    /// Outward unit normal where the ray along `d` meets `surface` at `t`,
    /// axial parameter `u`.
    fn normal(&self, d: &Vector3<f64>, t: f64, u: f64, surface: Surface) -> Vector3<f64> {
        match (self.ends, surface) {
            (Ends::Flat, Surface::EndA) if self.len > 1e-9 => -self.axis,
            (Ends::Flat, Surface::EndB) if self.len > 1e-9 => self.axis,
            // one division, not one a component (the shading reads it in f32)
            _ => {
                let out = d * t - (self.a + (self.b - self.a) * u);
                out * (1.0 / out.norm())
            }
        }
    }
}

impl Scene {
    /// Whether the ray through pixel position `(u, v)` (its unit direction
    /// from `ray`, asked only if a body's box holds the pixel) meets any of
    /// the bodies `candidates`.
    #[inline]
    pub(crate) fn any_hit(
        &self,
        candidates: &[u16],
        u: f64,
        v: f64,
        ray: impl Fn() -> Vector3<f64>,
    ) -> bool {
        let mut d = None;
        candidates.iter().any(|&i| {
            let body = &self.bodies[usize::from(i)];
            body.box_holds(u, v) && body.meets(d.get_or_insert_with(&ray))
        })
    }

    /// The first body among `candidates` the ray through pixel position
    /// `(u, v)` meets, and the ray: one ray at a time, the reference
    /// [`RayBatch`] and the tiles' lanes are held to.
    #[cfg(test)]
    pub(crate) fn first_hit(
        &self,
        camera: &Camera,
        candidates: &[u16],
        u: f64,
        v: f64,
    ) -> (Option<SurfaceHit>, Vector3<f64>) {
        let d = unit_ray(camera, u, v);
        (self.first_hit_along(candidates, u, v, &d), d)
    }

    /// The first body among `candidates` the ray along unit `d`, through
    /// pixel position `(u, v)`, meets (the reference, as [`Scene::first_hit`]).
    #[cfg(test)]
    pub(crate) fn first_hit_along(
        &self,
        candidates: &[u16],
        pu: f64,
        pv: f64,
        d: &Vector3<f64>,
    ) -> Option<SurfaceHit> {
        let mut best: Option<(f64, f64, Surface, usize)> = None;
        for &i in candidates {
            let i = usize::from(i);
            if best.is_some_and(|b| b.0 < self.bodies[i].near) {
                break; // candidates come nearest first
            }
            if !self.bodies[i].box_holds(pu, pv) {
                continue;
            }
            if let Some((t, u, s)) = self.bodies[i].hit(d)
                && best.is_none_or(|b| t < b.0)
            {
                best = Some((t, u, s, i));
            }
        }
        best.map(|(t, u, s, i)| self.surface_hit(d, t, u, s, i))
    }

    /// The hit of the ray along unit `d` on body `i` at distance `t`, axial
    /// parameter `u`, surface `s`.
    #[inline]
    fn surface_hit(&self, d: &Vector3<f64>, t: f64, u: f64, s: Surface, i: usize) -> SurfaceHit {
        let body = &self.bodies[i];
        SurfaceHit {
            t,
            body: i,
            normal: body.normal(d, t, u, s),
            arc_mm: body.arc[0] + u * (body.arc[1] - body.arc[0]),
            on_end: s != Surface::Side,
        }
    }
}

/// Box `[x_min, y_min, x_max, y_max]` of the pinhole directions `(x/z,
/// y/z)` of a sphere (centre `c` in the camera frame, radius `r`, mm):
/// along each axis, where the planes through the centre of projection
/// touch the sphere (the tangent lines of its disc in the (axis, z) plane).
/// `None` where the sphere reaches the camera's plane, so that no finite
/// box holds it. The pinhole image of a capsule is the convex hull of its
/// end spheres' images, so the union of their boxes holds it.
pub(crate) fn pinhole_box(c: Vector3<f64>, r: f64) -> Option<[f64; 4]> {
    let along = |x: f64| -> Option<(f64, f64)> {
        let rho = x.hypot(c.z);
        if rho <= r {
            return None;
        }
        let (alpha, delta) = (x.atan2(c.z), (r / rho).asin());
        let (lo, hi) = (alpha - delta, alpha + delta);
        let limit = std::f64::consts::FRAC_PI_2 - 1e-9;
        if lo <= -limit || hi >= limit {
            return None;
        }
        Some((lo.tan(), hi.tan()))
    };
    let (x0, x1) = along(c.x)?;
    let (y0, y1) = along(c.y)?;
    Some([x0, y0, x1, y1])
}

/// Pixel box `[u_min, v_min, u_max, v_max]` of everything whose pinhole
/// directions lie in `[x0, y0, x1, y1]`, seen by `camera`, lens included.
///
/// The lens scales each direction by `s(r_u) ≤ 1`, falling with `r_u`, while
/// `r_u s(r_u)` rises: so `x_d = x s` rises with `x` and, for `x` of one
/// sign, is largest in magnitude where `|y|` is smallest. The box's
/// distorted extremes are therefore on its corners or where its edges cross
/// an axis (a straight edge bows outward under barrel distortion).
pub(crate) fn image_box(camera: &Camera, [x0, y0, x1, y1]: [f64; 4]) -> [f64; 4] {
    let lens = &camera.lens;
    // the |y| nearest and farthest from the axis over [y0, y1], and likewise for x
    let near = |lo: f64, hi: f64| {
        if lo <= 0.0 && hi >= 0.0 {
            0.0
        } else {
            lo.abs().min(hi.abs())
        }
    };
    let far = |lo: f64, hi: f64| lo.abs().max(hi.abs());
    let (ny, fy, nx, fx) = (near(y0, y1), far(y0, y1), near(x0, x1), far(x0, x1));
    // an extreme x_d at x: outward (|x_d| largest) nearest the axis in y, inward farthest
    let xd = |x: f64, outward: bool| lens.distort(x, if outward { ny } else { fy })[0];
    let yd = |y: f64, outward: bool| lens.distort(if outward { nx } else { fx }, y)[1];
    let k = &camera.intrinsics;
    [
        k.fx * xd(x0, x0 < 0.0) + k.cx,
        k.fy * yd(y0, y0 < 0.0) + k.cy,
        k.fx * xd(x1, x1 > 0.0) + k.cx,
        k.fy * yd(y1, y1 > 0.0) + k.cy,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::instrument::Instrument;

    /// A hit's bits, to compare two casts exactly.
    fn bits(h: &SurfaceHit) -> (u64, usize, Vector3<u64>, u64, bool) {
        (
            h.t.to_bits(),
            h.body,
            h.normal.map(f64::to_bits),
            h.arc_mm.to_bits(),
            h.on_end,
        )
    }

    /// Casting a tile's rays body by body finds, pixel for pixel, the hit a
    /// lone ray finds through the nearest-first list, bit for bit.
    #[test]
    fn a_tiles_centre_hits_are_the_lone_rays_hits() {
        let instrument = Instrument::kflex();
        let cameras = [
            Camera::default(),
            Camera::default().with_intrinsics(Intrinsics::full_hd()),
        ];
        let mut raster = Rasterizer::new();
        let mut in_windows = 0;
        for camera in &cameras {
            let k = camera.intrinsics;
            for (theta, d) in [(-40.0, 12.0), (0.0, 10.0), (35.0, 20.0), (80.0, 38.0)] {
                let shape = instrument.shape(theta, d).expect("shape");
                raster.prepare(camera, &shape);
                for window in [
                    Roi::whole(k.width, k.height),
                    Roi {
                        x0: k.width / 5 + 1,
                        y0: k.height / 5 + 3,
                        width: k.width / 2 + 5,
                        height: k.height / 2 + 7,
                    },
                ] {
                    let mut tiled = Vec::new();
                    raster.centre_hits(camera, window, |x, y, hit| tiled.push((x, y, hit)));
                    let mut lone = Vec::new();
                    raster.tiles(camera, window, |scene, optics, [x0, y0, x1, y1], bodies| {
                        for y in y0..y1 {
                            for x in x0..x1 {
                                let (u, v) = (f64::from(x) + 0.5, f64::from(y) + 0.5);
                                if let Some(hit) =
                                    scene.first_hit_along(bodies, u, v, &optics.ray(x, y))
                                {
                                    lone.push((x, y, hit));
                                }
                            }
                        }
                    });
                    if window.area() == u64::from(k.width) * u64::from(k.height) {
                        assert!(lone.len() > 100, "θ = {theta}, d = {d}: {}", lone.len());
                    } else {
                        in_windows += lone.len();
                    }
                    assert_eq!(tiled.len(), lone.len(), "θ = {theta}, d = {d}");
                    for ((x, y, a), (lx, ly, b)) in tiled.iter().zip(&lone) {
                        assert_eq!((x, y), (lx, ly));
                        assert_eq!(bits(a), bits(b), "θ = {theta}, d = {d}, pixel ({x}, {y})");
                    }
                }
            }
        }
        assert!(in_windows > 100, "{in_windows}");
    }

    /// Rays through any pixel positions, cast a batch at a time (more than
    /// a batch holds, and part of one), meet what a lone ray meets, bit for
    /// bit: the four rays inside each pixel that shade the edges.
    #[test]
    fn a_batch_of_rays_meets_what_lone_rays_meet() {
        let camera = Camera::default();
        let mut raster = Rasterizer::new();
        let mut batch = RayBatch::default();
        let (mut hits, mut misses) = (0, 0);
        for (theta, d) in [(-80.0, 8.0), (0.0, 10.0), (60.0, 30.0)] {
            let shape = Instrument::kflex().shape(theta, d).expect("shape");
            raster.prepare(&camera, &shape);
            let k = camera.intrinsics;
            raster.tiles(
                &camera,
                Roi::whole(k.width, k.height),
                |scene, _, [x0, y0, x1, y1], bodies| {
                    let points: Vec<(f64, f64)> = (y0..y1)
                        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
                        .flat_map(|(x, y)| {
                            [(0.125, 0.875), (0.625, 0.375), (0.5, 0.5)]
                                .map(|(dx, dy)| (f64::from(x) + dx, f64::from(y) + dy))
                        })
                        .take(100 + (x0 % 3) as usize * 40)
                        .collect();
                    let mut seen = 0;
                    batch.first_hits(&camera, scene, bodies, &points, |i, hit, d| {
                        assert_eq!(i, seen);
                        seen += 1;
                        let (u, v) = points[i];
                        let (lone, ld) = scene.first_hit(&camera, bodies, u, v);
                        assert_eq!(d.map(f64::to_bits), ld.map(f64::to_bits));
                        assert_eq!(
                            hit.as_ref().map(bits),
                            lone.as_ref().map(bits),
                            "θ = {theta}, d = {d}, ({u}, {v})"
                        );
                        if hit.is_some() {
                            hits += 1;
                        } else {
                            misses += 1;
                        }
                    });
                    assert_eq!(seen, points.len());
                },
            );
        }
        assert!(hits > 1000 && misses > 1000, "{hits} {misses}");
    }

    /// A window inside the last one walked takes that walk's tiles: the
    /// same tiles and candidates, in the same order, as a walk of its own
    /// (a fresh rasterizer's), tiles outside it dropped and those across
    /// its edge clipped; a window outside it, another shape or another
    /// camera walks again.
    #[test]
    fn a_window_inside_the_last_walk_takes_its_tiles() {
        type Walk = Vec<([u32; 4], Vec<u16>)>;
        fn walk(raster: &mut Rasterizer, camera: &Camera, window: Roi) -> Walk {
            let mut seen = Vec::new();
            raster.tiles(camera, window, |_, _, tile, bodies| {
                seen.push((tile, bodies.to_vec()))
            });
            seen
        }
        let camera = Camera::default();
        let k = camera.intrinsics;
        let roi = |[x0, y0, width, height]: [u32; 4]| Roi {
            x0,
            y0,
            width,
            height,
        };
        let work = roi([101, 77, 303, 251]);
        // inside it: grown by a pixel (as a frame's shading), on the 8 and
        // 32 px lines of the tiles, small; then not inside it
        let windows = [
            roi([102, 78, 301, 249]),
            roi([104, 80, 296, 248]),
            roi([200, 150, 40, 30]),
            work,
            roi([90, 78, 301, 249]),
            Roi::whole(k.width, k.height),
        ];
        let (mut replayed, mut dropped, mut clipped) = (0, 0, 0);
        for (theta, d) in [(-60.0, 8.0), (0.0, 10.0), (45.0, 30.0)] {
            let shape = Instrument::kflex().shape(theta, d).expect("shape");
            let other = Instrument::kflex().shape(theta + 20.0, d).expect("shape");
            let mut first_walk = Rasterizer::new();
            first_walk.prepare(&camera, &shape);
            // the whole image's tiles (8 px each: its sides are multiples
            // of 8), clipped to a window by hand, in their order
            let whole = walk(&mut first_walk, &camera, Roi::whole(k.width, k.height));
            assert!(
                whole
                    .iter()
                    .all(|(b, _)| b[2] - b[0] == FINE && b[3] - b[1] == FINE)
            );
            let clip = |w: Roi| -> Walk {
                let (x1, y1) = (w.x0 + w.width, w.y0 + w.height);
                let boxes = whole.iter().map(|(b, c)| {
                    let b = [b[0].max(w.x0), b[1].max(w.y0), b[2].min(x1), b[3].min(y1)];
                    (b, c.clone())
                });
                boxes.filter(|(b, _)| b[0] < b[2] && b[1] < b[3]).collect()
            };
            let first = walk(&mut first_walk, &camera, work);
            assert_eq!(first, clip(work));
            assert!(first.len() > 20, "{}", first.len());
            for (s, window) in windows
                .iter()
                .map(|&w| (&shape, w))
                .chain([(&other, windows[0])])
            {
                let mut fresh = Rasterizer::new();
                fresh.prepare(&camera, s);
                let own = walk(&mut fresh, &camera, window);
                let mut again = Rasterizer::new();
                again.prepare(&camera, &shape);
                assert_eq!(walk(&mut again, &camera, work), first);
                let same = std::ptr::eq(s, &shape);
                if !same {
                    again.prepare(&camera, s);
                }
                let got = walk(&mut again, &camera, window);
                assert_eq!(got, own, "θ = {theta}, d = {d}, {window:?}");
                if same {
                    assert_eq!(got, clip(window), "θ = {theta}, d = {d}, {window:?}");
                }
                // taken from the walk over `work`, or walked again
                let kept = same && work.holds(&window);
                let over = if kept { work } else { window };
                assert_eq!(again.walked_over, Some((camera, over)), "{window:?}");
                if kept {
                    replayed += 1;
                    dropped += first.len() - got.len();
                    // a box that is not its tile's in the walk over `work`
                    let corner = |b: [u32; 4]| [b[0] / FINE, b[1] / FINE];
                    clipped += got
                        .iter()
                        .filter(|(b, _)| !first.iter().any(|(f, _)| f == b))
                        .filter(|(b, _)| first.iter().any(|(f, _)| corner(*f) == corner(*b)))
                        .count();
                }
            }
        }
        assert_eq!(replayed, 12);
        assert!(dropped > 20 && clipped > 20, "{dropped} {clipped}");
        // another camera, the shape not prepared again: walked again
        let shape = Instrument::kflex().shape(0.0, 10.0).expect("shape");
        let mut raster = Rasterizer::new();
        raster.prepare(&camera, &shape);
        let _ = walk(&mut raster, &camera, work);
        let mut moved = camera;
        moved.intrinsics.cx += 7.0;
        let _ = walk(&mut raster, &moved, windows[0]);
        assert_eq!(raster.walked_over, Some((moved, windows[0])));
    }

    /// The AVX2 copy of the lane cast gives the portable one's bits, lane
    /// for lane (on a processor without AVX2 both are the portable one).
    #[test]
    fn the_wide_lane_cast_is_the_portable_one() {
        let camera = Camera::default();
        let mut raster = Rasterizer::new();
        let mut tiles = 0;
        for (theta, d) in [(-70.0, 5.0), (0.0, 10.0), (45.0, 25.0), (90.0, 40.0)] {
            let shape = Instrument::kflex().shape(theta, d).expect("shape");
            raster.prepare(&camera, &shape);
            let k = camera.intrinsics;
            raster.tiles(
                &camera,
                Roi::whole(k.width, k.height),
                |scene, optics, tile, bodies| {
                    let (mut narrow, mut wide) = (Lanes::default(), Lanes::default());
                    narrow.load(optics, tile);
                    wide.load(optics, tile);
                    narrow.cast(&scene.bodies, bodies, false);
                    wide.cast(&scene.bodies, bodies, Lanes::wide());
                    let bits = |l: &Lanes| [l.t, l.u, l.s, l.i].map(|a| a.map(f64::to_bits));
                    assert_eq!(
                        bits(&narrow),
                        bits(&wide),
                        "θ = {theta}, d = {d}, tile {tile:?}"
                    );
                    tiles += 1;
                },
            );
        }
        assert!(tiles > 100, "{tiles}");
    }
}
