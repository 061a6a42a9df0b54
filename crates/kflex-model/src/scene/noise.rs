//! Smooth noise for the procedural backgrounds: value noise on a hashed
//! integer lattice (quintic interpolation) and its fractal sum (fBm), each
//! octave rotated so the lattice's axes do not show.

/// A seeded smooth noise field over the plane.
#[derive(Debug, Clone, Copy)]
pub(super) struct Noise {
    seed: u32,
}

/// Each octave is turned by this angle (cos, sin of about 37°) and scaled by
/// this lacunarity, so no two octaves share lattice lines.
const TURN: (f32, f32) = (0.798_6, 0.601_8);
const LACUNARITY: f32 = 2.03;

impl Noise {
    /// The field for `seed`, stream `stream` (independent fields from one seed).
    pub(super) fn new(seed: u64, stream: u64) -> Self {
        let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        Self {
            seed: (z ^ (z >> 31)) as u32,
        }
    }

    /// Uniform in [0, 1) at lattice point `(i, j)`.
    #[inline(always)]
    fn lattice(&self, i: i32, j: i32) -> f32 {
        let mut h =
            (i as u32).wrapping_mul(0x8DA6_B343) ^ (j as u32).wrapping_mul(0xD816_3841) ^ self.seed;
        h ^= h >> 15;
        h = h.wrapping_mul(0x2C1B_3C6D);
        h ^= h >> 12;
        h = h.wrapping_mul(0x297A_2D39);
        h ^= h >> 15;
        (h >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Value noise in [0, 1], continuous with continuous first and second
    /// derivatives (quintic fade), one feature per unit.
    #[inline]
    pub(super) fn value(&self, x: f32, y: f32) -> f32 {
        let (xf, yf) = (x.floor(), y.floor());
        let (i, j) = (xf as i32, yf as i32);
        let (fx, fy) = (x - xf, y - yf);
        let fade = |t: f32| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
        let (sx, sy) = (fade(fx), fade(fy));
        let a = self.lattice(i, j);
        let b = self.lattice(i + 1, j);
        let c = self.lattice(i, j + 1);
        let d = self.lattice(i + 1, j + 1);
        let top = a + (b - a) * sx;
        let bottom = c + (d - c) * sx;
        top + (bottom - top) * sy
    }

    /// Fractal Brownian motion: `octaves` octaves of [`Noise::value`], each
    /// twice the frequency and half the amplitude of the last; in [0, 1],
    /// mean about ½.
    pub(super) fn fbm(&self, x: f32, y: f32, octaves: u32) -> f32 {
        let (mut x, mut y) = (x, y);
        let (mut sum, mut amp, mut norm) = (0.0, 1.0, 0.0);
        for o in 0..octaves {
            // offset each octave so they do not all pass through the origin's lattice value
            sum += amp * self.value(x + 17.3 * o as f32, y - 9.1 * o as f32);
            norm += amp;
            amp *= 0.5;
            (x, y) = (
                LACUNARITY * (TURN.0 * x - TURN.1 * y),
                LACUNARITY * (TURN.1 * x + TURN.0 * y),
            );
        }
        sum / norm
    }

    /// [`Noise::fbm`] centred on zero: in [−½, ½].
    #[inline]
    pub(super) fn signed(&self, x: f32, y: f32, octaves: u32) -> f32 {
        self.fbm(x, y, octaves) - 0.5
    }
}

/// Hermite step from 0 at `e0` to 1 at `e1` (either order).
#[inline]
pub(super) fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_bounded_smooth_and_seeded() {
        let (a, b) = (Noise::new(1, 0), Noise::new(2, 0));
        let mut differ = 0;
        for k in 0..2000 {
            let (x, y) = (k as f32 * 0.173 - 50.0, k as f32 * 0.091 + 3.0);
            let v = a.fbm(x, y, 5);
            assert!((0.0..=1.0).contains(&v), "{v}");
            // continuous: a step of 1e-3 moves it little
            assert!((a.fbm(x + 1e-3, y, 5) - v).abs() < 0.05);
            if (b.fbm(x, y, 5) - v).abs() > 1e-3 {
                differ += 1;
            }
        }
        assert!(differ > 1900);
    }
}
