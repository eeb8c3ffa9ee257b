//! Property tests of the pure physics (`stereo_core::physics`): the laws the service's
//! answers rest on, checked over many generated rigs and correspondences rather than a few
//! hand-picked numbers. Run more cases with `PROPTEST_CASES=100000 cargo test --test
//! physics_properties`.

use proptest::prelude::*;
use stereo_core::physics::{
    self, Correspondence, FocalLength, LengthUnit, PhysicsError, Rig, RigSpec, SampleRange, Spacing,
};

/// `a` and `b` agree to `rel` relative (absolute below 1e-300).
fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-300)
}

/// Any finite f64 of either sign, subnormals and zeros included: the inputs a JSON number can
/// carry.
fn any_finite() -> impl Strategy<Value = f64> {
    use proptest::num::f64::{NEGATIVE, NORMAL, POSITIVE, SUBNORMAL, ZERO};
    POSITIVE | NEGATIVE | NORMAL | SUBNORMAL | ZERO
}

/// A positive magnitude spread evenly over many decades, `10^lo ..= 10^hi`.
fn decades(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    (lo..=hi).prop_map(|e| 10f64.powf(e))
}

fn unit() -> impl Strategy<Value = LengthUnit> {
    prop::sample::select(LengthUnit::ALL.to_vec())
}

/// A physically sensible rig, across the scales of real ones (microscopes to long-baseline
/// survey rigs), with any unit.
fn rig() -> impl Strategy<Value = Rig> {
    (
        decades(0.0, 5.0),  // focal length, px
        decades(-3.0, 4.0), // baseline
        unit(),
        16u32..20_000,      // image width
        16u32..20_000,      // image height
        -100.0..100.0f64,   // doffs
        decades(-3.0, 1.0), // Δd
    )
        .prop_map(|(focal_px, baseline, unit, w, h, doffs, dd)| {
            let mut spec = RigSpec::pixels(focal_px, baseline, unit);
            spec.camera.image_width = Some(w);
            spec.camera.image_height = Some(h);
            spec.camera.disparity_error_px = Some(dd);
            spec.doffs = Some(doffs);
            Rig::new(&spec).expect("a sensible rig is a rig")
        })
}

/// A correspondence inside `rig`'s image.
fn inside(rig: &Rig) -> impl Strategy<Value = Correspondence> + use<> {
    let (width, height) = (
        rig.image_width().unwrap_or(1.0),
        rig.image_height().unwrap_or(1.0),
    );
    (0.0..=width, 0.0..=width, 0.0..=height)
        .prop_map(|(x_left, x_right, y)| Correspondence::from_pair(x_left, x_right, y))
}

proptest! {
    /// Triangulation: Z·|d + doffs| = B·f, and Z is in the baseline's unit (positive).
    #[test]
    fn depth_times_disparity_is_focal_times_baseline(
        (rig, c) in rig().prop_flat_map(|r| (Just(r), inside(&r)))
    ) {
        let effective = c.disparity_px + rig.doffs();
        match physics::measure(&rig, c) {
            Ok(m) => {
                prop_assert!(m.distance > 0.0);
                prop_assert!(close(m.distance * effective.abs(), rig.focal_px() * rig.baseline(), 1e-12));
                // A rig with an image size has a principal point, so every point is placed.
                let (p, range) = (m.point.unwrap(), m.range.unwrap());
                prop_assert_eq!(p.z, m.distance);
                prop_assert!(close(m.distance_m, m.distance * rig.unit().metres(), 1e-12));
                // The range is the length of the point vector, never shorter than the depth.
                prop_assert!(close(range * range, p.x * p.x + p.y * p.y + p.z * p.z, 1e-9));
                prop_assert!(range >= m.distance);
            }
            Err(e) => prop_assert_eq!(e, PhysicsError::AtInfinity, "only d + doffs = 0 fails here"),
        }
    }

    /// The four ways of giving a focal length agree, and each inverts: f in mm back from f in
    /// px through the sensor width or the pixel pitch, and the FOV back from f in px.
    #[test]
    fn focal_conversions_round_trip(
        focal_px in decades(0.0, 5.0),
        width in 16u32..20_000,
        pitch_um in decades(-1.0, 1.5),
    ) {
        let width = f64::from(width);
        let sensor_width_mm = width * pitch_um / 1000.0;
        let focal_mm = focal_px * pitch_um / 1000.0;
        let by_sensor = FocalLength::MillimetresWithSensorWidth { focal_mm, sensor_width_mm }
            .to_pixels(width)
            .unwrap();
        let by_pitch = FocalLength::MillimetresWithPixelPitch { focal_mm, pixel_pitch_um: pitch_um }
            .to_pixels(width)
            .unwrap();
        let degrees = physics::field_of_view_deg(focal_px, width);
        let by_fov = FocalLength::HorizontalFov { degrees }.to_pixels(width).unwrap();
        prop_assert!(close(by_sensor, focal_px, 1e-12), "sensor: {by_sensor} vs {focal_px}");
        prop_assert!(close(by_pitch, focal_px, 1e-12), "pitch: {by_pitch} vs {focal_px}");
        // tan near 0° loses digits as the FOV shrinks; 1e-9 holds to f = 10^5 px.
        prop_assert!(close(by_fov, focal_px, 1e-9), "fov {degrees}°: {by_fov} vs {focal_px}");
        prop_assert!(degrees > 0.0 && degrees < 180.0);
        prop_assert_eq!(FocalLength::Pixels(focal_px).to_pixels(width), Ok(focal_px));
    }

    /// Distance falls as the effective disparity grows, on either side of zero.
    #[test]
    fn distance_is_monotone_in_disparity(
        rig in rig(),
        a in decades(-3.0, 4.0),
        b in decades(-3.0, 4.0),
        negative in any::<bool>(),
    ) {
        let (near, far) = if a >= b { (a, b) } else { (b, a) };
        let sign = if negative { -1.0 } else { 1.0 };
        let z_near = rig.distance_at(sign * near - rig.doffs()).unwrap();
        let z_far = rig.distance_at(sign * far - rig.doffs()).unwrap();
        prop_assert!(z_near <= z_far, "Z({near}) = {z_near} > Z({far}) = {z_far}");
        if near > far * (1.0 + 1e-9) {
            prop_assert!(z_near < z_far);
        }
    }

    /// Unit conversions compose (a→b→c is a→c), invert (a→b→a is the identity), and carry
    /// through the physics: the same rig with its baseline in another unit gives the same
    /// distance and error in that unit.
    #[test]
    fn unit_conversions_compose(
        value in decades(-6.0, 6.0),
        (a, b, c) in (unit(), unit(), unit()),
        (rig, corr) in rig().prop_flat_map(|r| (Just(r), inside(&r))),
    ) {
        prop_assert!(close(b.convert(a.convert(value, b), c), a.convert(value, c), 1e-14));
        prop_assert!(close(b.convert(a.convert(value, b), a), value, 1e-14));

        let other = rig.in_unit(b);
        prop_assert!(close(other.baseline(), rig.unit().convert(rig.baseline(), b), 1e-14));
        if let (Ok(here), Ok(there)) = (physics::measure(&rig, corr), physics::measure(&other, corr)) {
            prop_assert!(close(rig.unit().convert(here.distance, b), there.distance, 1e-12));
            prop_assert!(close(rig.unit().convert(here.depth_error, b), there.depth_error, 1e-12));
            prop_assert!(close(here.distance_m, there.distance_m, 1e-12));
            prop_assert!(close(here.relative_error, there.relative_error, 1e-12));
        }
    }

    /// The depth error is ΔZ = Z²·Δd/(f·B): it grows as Z², k times farther is k² times the
    /// error, and it is linear in Δd.
    #[test]
    fn depth_error_grows_as_distance_squared(
        rig in rig(),
        distance in decades(-2.0, 4.0),
        k in 1.0..100.0f64,
    ) {
        let e = rig.depth_error_at(distance);
        prop_assert!(close(e, distance * distance * rig.disparity_error_px() / (rig.focal_px() * rig.baseline()), 1e-12));
        prop_assert!(close(rig.depth_error_at(k * distance), k * k * e, 1e-12));
        let doubled = rig.with_disparity_error(2.0 * rig.disparity_error_px()).unwrap();
        prop_assert!(close(doubled.depth_error_at(distance), 2.0 * e, 1e-12));
        // The inverse problem gives back the baseline the error came from.
        let baseline = physics::baseline_for(rig.focal_px(), distance, e, rig.disparity_error_px()).unwrap();
        prop_assert!(close(baseline, rig.baseline(), 1e-12));
    }

    /// Over any finite numbers at all, valid or not, the core never panics, and whatever it
    /// answers without an error is finite.
    #[test]
    fn any_finite_input_is_finite_or_an_error(
        focal_px in any_finite(), baseline in any_finite(), doffs in any_finite(),
        width in any_finite(), height in any_finite(), dd in any_finite(),
        x_left in any_finite(), x_right in any_finite(), y in any_finite(),
        lo in any_finite(), hi in any_finite(), count in 0usize..64,
        log in any::<bool>(), unit in unit(),
        focal_mm in any_finite(), per in any_finite(),
    ) {
        // Whatever rig the constructor makes of any magnitudes (it refuses the ones whose
        // product or ratio overflows, and zeros).
        let mut spec = RigSpec::pixels(focal_px.abs(), baseline.abs(), unit);
        spec.camera.focal_y_px = Some(focal_mm.abs());
        spec.camera.image_width = Some(width.abs() as u32);
        spec.camera.image_height = Some(height.abs() as u32);
        spec.camera.disparity_error_px = Some(dd.abs());
        spec.doffs = Some(doffs);
        if let Ok(rig) = Rig::new(&spec) {
            let spacing = if log { Spacing::Log } else { Spacing::Linear };
            if let Ok(m) = physics::measure(&rig, Correspondence::from_pair(x_left, x_right, y)) {
                let p = m.point.unwrap_or(physics::Point3 { x: 0.0, y: 0.0, z: 0.0 });
                for v in [m.disparity_px, m.effective_disparity_px, m.distance, m.distance_m,
                          m.depth_error, m.relative_error, m.normalized_x.unwrap_or(0.0),
                          m.projection_factor, m.range.unwrap_or(0.0), p.x, p.y, p.z] {
                    prop_assert!(v.is_finite(), "{m:?}");
                }
            }
            for range in [SampleRange::Distance { min: lo, max: hi }, SampleRange::Disparity { min: lo, max: hi }] {
                if let Ok(samples) = physics::sweep(&rig, range, count, spacing) {
                    prop_assert_eq!(samples.len(), count);
                    for s in samples {
                        prop_assert!(s.disparity_px.is_finite() && s.distance.is_finite() && s.depth_error.is_finite());
                    }
                }
                if let Ok(rows) = physics::table(&rig, range, count, spacing, x_left) {
                    for r in rows {
                        prop_assert!([r.distance, r.disparity_px, r.normalized_x.unwrap_or(0.0), r.projection_factor, r.depth_error]
                            .iter()
                            .all(|v| v.is_finite()));
                    }
                }
            }
            if let Some(z) = rig.distance_at_relative_error(per) {
                prop_assert!(z.is_finite());
            }
            if let Ok((near, far)) = rig.depth_range(lo, hi) {
                prop_assert!(near.is_finite() && far.is_finite());
            }
        }
        if let Ok(b) = physics::baseline_for(focal_px, lo, hi, dd) {
            prop_assert!(b.is_finite());
        }
        for focal in [
            FocalLength::Pixels(focal_px),
            FocalLength::MillimetresWithSensorWidth { focal_mm, sensor_width_mm: per },
            FocalLength::MillimetresWithPixelPitch { focal_mm, pixel_pitch_um: per },
            FocalLength::HorizontalFov { degrees: per },
        ] {
            if let Ok(f) = focal.to_pixels(width) {
                prop_assert!(f.is_finite());
            }
        }
    }
}
