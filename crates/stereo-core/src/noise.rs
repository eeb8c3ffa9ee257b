//! Seeded random numbers and the band-limited noise textures that the renders with exact
//! truth (stereo scenes, checkerboards seen through lenses) and the tests draw from, so that
//! every render is the same on every machine.

/// A small deterministic generator (SplitMix64).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Standard normal (Box–Muller).
    pub fn normal(&mut self) -> f32 {
        let u = self.unit().max(1e-7);
        let v = self.unit();
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    }
}

/// A band-limited texture: a sum of plane waves below 0.4 cycles a pixel, in [0, 1].
pub struct Texture {
    waves: Vec<([f32; 2], f32, f32)>,
}

impl Texture {
    pub fn new(seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let waves = (0..24)
            .map(|i| {
                // Octaves from coarse to fine, so the texture has structure at every scale.
                let f = 0.015 * 1.19f32.powi(i) * (0.8 + 0.4 * rng.unit());
                let angle = rng.unit() * std::f32::consts::PI;
                let amplitude = 1.0 / (1.0 + 6.0 * f);
                (
                    [f * angle.cos(), f * angle.sin()],
                    rng.unit() * std::f32::consts::TAU,
                    amplitude,
                )
            })
            .collect::<Vec<_>>();
        Self { waves }
    }

    /// The texture's value at (x, y), in its own pixels.
    pub fn at(&self, x: f32, y: f32) -> f32 {
        let total: f32 = self.waves.iter().map(|w| w.2).sum();
        let v: f32 = self
            .waves
            .iter()
            .map(|&([fx, fy], phase, a)| {
                a * (std::f32::consts::TAU * (fx * x + fy * y) + phase).sin()
            })
            .sum();
        (0.5 + 0.9 * v / total).clamp(0.0, 1.0)
    }
}
