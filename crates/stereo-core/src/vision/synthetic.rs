//! Rectified stereo pairs rendered with exact ground truth, for the tests, the benchmarks and
//! the page's sample: textured planes (fronto-parallel or slanted) at known disparities, in
//! front of one another so that they occlude, seen by two cameras that may differ in gain,
//! offset and noise. No third-party image is involved.
//!
//! A plane's disparity is affine in the left image, `d(x, y) = a + b·x + c·y`, which is exactly
//! what a plane in space gives a rectified pair. Its texture is attached to the surface (a
//! function of the left image's coordinates), so the right camera sees the same texture
//! shifted and, for a slanted plane, stretched.

use super::Gray;

pub use crate::noise::{Rng, Texture};

/// Where a plane is, in the left image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Region {
    Everywhere,
    Rect { x0: f32, y0: f32, x1: f32, y1: f32 },
    Disc { cx: f32, cy: f32, r: f32 },
}

impl Region {
    fn contains(&self, x: f32, y: f32) -> bool {
        match *self {
            Region::Everywhere => true,
            Region::Rect { x0, y0, x1, y1 } => x >= x0 && x < x1 && y >= y0 && y < y1,
            Region::Disc { cx, cy, r } => (x - cx).powi(2) + (y - cy).powi(2) < r * r,
        }
    }
}

/// A textured plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// `d(x, y) = a + b·x + c·y` in the left image, in pixels.
    pub disparity: [f32; 3],
    pub region: Region,
    /// Selects the texture.
    pub seed: u64,
    /// The plane's colour (multiplies the texture per channel).
    pub tint: [f32; 3],
}

impl Plane {
    fn disparity_at(&self, x: f32, y: f32) -> f32 {
        let [a, b, c] = self.disparity;
        a + b * x + c * y
    }
}

/// A scene and the cameras' differences.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    pub width: usize,
    pub height: usize,
    /// Planes; where several cover a pixel, the nearest (largest disparity) is seen.
    pub planes: Vec<Plane>,
    /// The right camera's response: `right = gain · value + offset` (value in [0, 1]).
    pub gain: f32,
    pub offset: f32,
    /// Standard deviation of independent noise added to each image, in [0, 1] units.
    pub noise: f32,
    pub seed: u64,
}

/// A rendered pair and its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct Pair {
    pub left: Gray,
    pub right: Gray,
    /// RGB, 8 bits a channel, of each image.
    pub left_rgb: Vec<u8>,
    pub right_rgb: Vec<u8>,
    /// The true disparity of each left pixel.
    pub truth: Vec<f32>,
    /// Whether the left pixel is seen by the right camera too (not occluded, not outside).
    pub visible: Vec<bool>,
}

impl Pair {
    /// The true disparities of the left pixels the right camera sees too, in row order.
    pub fn seen_truth(&self) -> Vec<f32> {
        self.truth
            .iter()
            .zip(&self.visible)
            .filter(|(_, seen)| **seen)
            .map(|(d, _)| *d)
            .collect()
    }
}

/// The weights of Catmull-Rom's cubic (OpenCV's `INTER_CUBIC` kernel, a = −0.5) for the four
/// samples around a point `t` (in [0, 1)) past the second of them: how the tests upscale an
/// image into one smooth over several pixels.
pub fn catmull_rom(t: f32) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// Renders `scene`.
pub fn render(scene: &Scene) -> Pair {
    let (w, h) = (scene.width, scene.height);
    let textures: Vec<Texture> = scene.planes.iter().map(|p| Texture::new(p.seed)).collect();
    let mut rng = Rng::new(scene.seed);
    let mut left_rgb = vec![0u8; w * h * 3];
    let mut right_rgb = vec![0u8; w * h * 3];
    let mut truth = vec![f32::NAN; w * h];
    let mut visible = vec![false; w * h];
    // Which plane each right pixel sees, for the visibility of left pixels.
    let mut right_plane = vec![usize::MAX; w * h];
    let put = |rgb: &mut [u8],
               i: usize,
               value: f32,
               tint: [f32; 3],
               gain: f32,
               offset: f32,
               rng: &mut Rng| {
        for (c, t) in tint.iter().enumerate() {
            let v = gain * value * t + offset + scene.noise * rng.normal();
            rgb[i * 3 + c] = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    };
    for y in 0..h {
        let yf = y as f32;
        for x in 0..w {
            let xf = x as f32;
            // Left: the nearest plane covering the pixel.
            let seen = scene
                .planes
                .iter()
                .enumerate()
                .filter(|(_, p)| p.region.contains(xf, yf))
                .max_by(|a, b| {
                    a.1.disparity_at(xf, yf)
                        .total_cmp(&b.1.disparity_at(xf, yf))
                });
            if let Some((i, p)) = seen {
                truth[y * w + x] = p.disparity_at(xf, yf);
                let value = textures[i].at(xf, yf);
                put(&mut left_rgb, y * w + x, value, p.tint, 1.0, 0.0, &mut rng);
            }
            // Right: each plane is seen at the left x with x − d(x) = x_r.
            let seen = scene
                .planes
                .iter()
                .enumerate()
                .filter_map(|(i, p)| {
                    let [a, b, c] = p.disparity;
                    let xl = (xf + a + c * yf) / (1.0 - b);
                    p.region
                        .contains(xl, yf)
                        .then(|| (i, xl, p.disparity_at(xl, yf)))
                })
                .max_by(|a, b| a.2.total_cmp(&b.2));
            if let Some((i, xl, _)) = seen {
                right_plane[y * w + x] = i;
                let value = textures[i].at(xl, yf);
                put(
                    &mut right_rgb,
                    y * w + x,
                    value,
                    scene.planes[i].tint,
                    scene.gain,
                    scene.offset,
                    &mut rng,
                );
            }
        }
    }
    for y in 0..h {
        for x in 0..w {
            let d = truth[y * w + x];
            if d.is_nan() {
                continue;
            }
            let xr = (x as f32 - d).round();
            if xr < 0.0 || xr >= w as f32 {
                continue;
            }
            let plane = scene
                .planes
                .iter()
                .enumerate()
                .filter(|(_, p)| p.region.contains(x as f32, y as f32))
                .max_by(|a, b| {
                    a.1.disparity_at(x as f32, y as f32)
                        .total_cmp(&b.1.disparity_at(x as f32, y as f32))
                })
                .map(|(i, _)| i);
            visible[y * w + x] = plane == Some(right_plane[y * w + xr as usize]);
        }
    }
    Pair {
        left: grey(&left_rgb, w, h),
        right: grey(&right_rgb, w, h),
        left_rgb,
        right_rgb,
        truth,
        visible,
    }
}

/// `rgb` (`width × height`) as a baseline JPEG of `quality` (1–100), the `image` crate's
/// encoder's.
pub fn jpeg(rgb: &[u8], width: usize, height: usize, quality: u8) -> Vec<u8> {
    let mut out = Vec::new();
    let encoder = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality);
    image::ImageEncoder::write_image(
        encoder,
        rgb,
        width as u32,
        height as u32,
        image::ExtendedColorType::Rgb8,
    )
    .expect("an RGB buffer of its size encodes");
    out
}

/// `rgb` (`width × height`, as stored) as a phone writes a photo: a JPEG with an EXIF
/// `orientation` (1: as stored; 6: turn 90° clockwise to show; 8: counter-clockwise; 3: 180°).
pub fn phone_jpeg(rgb: &[u8], width: usize, height: usize, orientation: u16) -> Vec<u8> {
    let jpeg = jpeg(rgb, width, height, 95);
    // TIFF header (big-endian), one IFD entry: 0x0112 Orientation, SHORT, one value.
    let mut app1 = b"Exif\0\0MM\0\x2a\0\0\0\x08\0\x01\x01\x12\0\x03\0\0\0\x01".to_vec();
    app1.extend_from_slice(&orientation.to_be_bytes());
    app1.extend_from_slice(&[0; 6]);
    let mut out = jpeg[..2].to_vec();
    out.extend_from_slice(&[0xFF, 0xE1]);
    out.extend_from_slice(&(app1.len() as u16 + 2).to_be_bytes());
    out.extend_from_slice(&app1);
    out.extend_from_slice(&jpeg[2..]);
    out
}

/// Grey levels of an RGB image (Rec. 709 weights, as the decoder's conversion), 16 bits.
pub fn grey(rgb: &[u8], width: usize, height: usize) -> Gray {
    let data = rgb
        .chunks_exact(3)
        .map(|p| {
            let l = 0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2]);
            (l * 257.0).round().min(65535.0) as u16
        })
        .collect();
    Gray::new(width, height, data)
}

/// The test scene: a slanted background plane, a box and a disc in front of it (occluding it),
/// `width × height`, disparities within 4..=40 px.
pub fn layered(width: usize, height: usize) -> Scene {
    let (w, h) = (width as f32, height as f32);
    Scene {
        width,
        height,
        planes: vec![
            Plane {
                disparity: [6.0, 8.0 / w, 2.0 / h],
                region: Region::Everywhere,
                seed: 1,
                tint: [0.9, 1.0, 0.8],
            },
            Plane {
                disparity: [22.0, 0.0, 0.0],
                region: Region::Rect {
                    x0: 0.15 * w,
                    y0: 0.2 * h,
                    x1: 0.45 * w,
                    y1: 0.75 * h,
                },
                seed: 2,
                tint: [1.0, 0.7, 0.6],
            },
            Plane {
                disparity: [30.0, -4.0 / w, 0.0],
                region: Region::Disc {
                    cx: 0.7 * w,
                    cy: 0.5 * h,
                    r: 0.22 * h,
                },
                seed: 3,
                tint: [0.6, 0.8, 1.0],
            },
        ],
        gain: 1.0,
        offset: 0.0,
        noise: 0.0,
        seed: 7,
    }
}

/// The test scene ([`layered`]) nearer: its disparities `times` as great and `plus` px
/// further (`nearer(640, 360, 5.0, 0.0)`: 30–200 px; with `plus` 60, near everywhere).
pub fn nearer(width: usize, height: usize, times: f32, plus: f32) -> Scene {
    let mut scene = layered(width, height);
    for plane in &mut scene.planes {
        plane.disparity = plane.disparity.map(|v| times * v);
        plane.disparity[0] += plus;
    }
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each visible left pixel's colour is found in the right image `d` pixels to the left.
    #[test]
    fn the_right_image_is_the_left_shifted_by_the_truth() {
        let pair = render(&Scene {
            planes: vec![Plane {
                disparity: [12.0, 0.0, 0.0],
                region: Region::Everywhere,
                seed: 4,
                tint: [1.0; 3],
            }],
            ..layered(80, 20)
        });
        for y in 0..20 {
            for x in 12..80 {
                assert!(pair.visible[y * 80 + x]);
                assert_eq!(pair.left.data[y * 80 + x], pair.right.data[y * 80 + x - 12]);
            }
            assert!(!pair.visible[y * 80 + 5]);
        }
    }

    /// The layered scene has occlusions beside its foreground objects, and not elsewhere.
    #[test]
    fn layered_scene_has_occlusions() {
        let pair = render(&layered(200, 120));
        let hidden = pair.visible.iter().filter(|v| !**v).count();
        assert!(hidden > 500 && hidden < 200 * 120 / 4, "{hidden}");
    }
}
