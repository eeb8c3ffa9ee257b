//! The matcher's run over a rectified pair: the pair's noise and texture judged, the
//! pyramid's levels matched coarse to fine in stripes side by side (census, cost, aggregation,
//! refinement, σ_d, filters), and each stage's time. [`super`] holds the types it reads and
//! writes; the stages are its siblings.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::{Cancelled, Disparity, Gray, Params};
use super::{census, cost, filters, pyramid, refine, sgm, sigma, stripes};

/// How long each stage took, in wall time: the stripes run side by side (and in waves when
/// there are more than cores), so their wall time is shared between the stages in proportion
/// to each stage's time summed over the stripes, and the three add up to the matcher's time.
/// With them, what the run decided as it went: the paths it aggregated.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timings {
    /// The census transform (the costs themselves are made inside the aggregation's passes,
    /// and counted there).
    pub cost: Duration,
    pub aggregate: Duration,
    /// Winner-takes-all, left-right check and the filters.
    pub refine: Duration,
    /// The paths the finest level aggregated ([`sgm::Paths::Auto`] decided); `None` before
    /// any level was matched.
    pub paths: Option<sgm::Paths>,
    /// The cost cells matched over every level and stripe, the context rows included: the
    /// count each pass of the matcher touches (the work budget in `docs/matcher.md`).
    pub cells: usize,
}

/// The disparity map of a rectified pair (the same size), or [`Cancelled`] when `cancel` was set
/// before the matcher finished; it is checked between stages and between rows. Stage times add
/// up to the matcher's wall time ([`Timings`]).
pub fn disparity(
    left: &Gray,
    right: &Gray,
    params: &Params,
    cancel: &AtomicBool,
) -> Result<(Disparity, Timings), Cancelled> {
    disparity_probed(left, right, params, cancel, &[]).map(|(map, timings, _)| (map, timings))
}

/// What the matcher saw at one pixel before its checks: the basis of a point's status in
/// [`correspond`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// The winner's index into the range, whatever the checks say.
    pub index: usize,
    /// The winner with its sub-pixel offset, as an index into the range.
    pub subpixel: f32,
    /// The winner's cost curve: its aggregated cost, the least more than one index away, the
    /// curvature there.
    pub cue: refine::Cue,
    /// How far the right image's winner at the match lies from the winner, in pixels
    /// ([`refine::disagreement`]).
    pub disagreement: f32,
    /// Whether the winner passes the uniqueness test.
    pub unique: bool,
    /// Whether the winner passes the left-right check (true when the check is off).
    pub consistent: bool,
    /// The raw census cost (bits) at the winner, averaged over the 5 × 5 window around the
    /// pixel; and the window's own least average cost, and its least more than one index away.
    pub window_cost: f32,
    pub window_best: f32,
    pub window_second: f32,
    /// The window's average cost over every disparity searched: what no match costs.
    pub window_mean: f32,
}

/// [`disparity`], also probing the pixels `wanted[y]` (the x of each, any order) of each row
/// `y`: the answer holds, for each row, one [`Probe`] per wanted pixel in the order given.
/// Rows past `wanted.len()` are probed nowhere.
pub fn disparity_probed(
    left: &Gray,
    right: &Gray,
    params: &Params,
    cancel: &AtomicBool,
    wanted: &[Vec<usize>],
) -> Result<(Disparity, Timings, Vec<Vec<Probe>>), Cancelled> {
    disparity_probed_in(
        left,
        right,
        PairNoise::of(left, right),
        params,
        cancel,
        wanted,
    )
}

/// What the census needs to know of the whole pair ([`census`]), measured once, so that a crop
/// of it (the bands [`correspond`] matches) is matched as the whole pair is: the standard
/// deviation of each image's noise (16-bit levels), which the census centres compare against,
/// the pixels between the census window's samples, whether its texture is faint (the
/// pyramid then goes further: [`pyramid::levels`]), and how clear it is (which paths
/// [`sgm::Paths::Auto`] and [`sgm::Paths::Lean`] take).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairNoise {
    pub left: f32,
    pub right: f32,
    pub stride: usize,
    pub faint: bool,
    /// [`census::Texture::clarity`].
    pub clarity: f32,
}

impl PairNoise {
    /// Each image's noise by the median form of Immerkær's estimate ([`census::noise_sigma`]),
    /// and what the pair's texture calls for ([`census::texture`]).
    pub fn of(left_image: &Gray, right_image: &Gray) -> PairNoise {
        let (left, right) = rayon::join(
            || census::noise_sigma(left_image),
            || census::noise_sigma(right_image),
        );
        let census::Texture {
            stride,
            faint,
            clarity,
        } = census::texture(left_image, right_image, (left, right));
        PairNoise {
            left,
            right,
            stride,
            faint,
            clarity: clarity as f32,
        }
    }

    /// The pair a level up the pyramid, where each pixel averages four: half the noise, and
    /// the census's samples one pixel apart. (Those levels only bound the finest level's
    /// search; halving the stride there instead, 4 → 2 on Motorcycle upscaled 4 ×, measured
    /// 26.03 % bad-1.0 against 25.53.)
    fn halved(self) -> PairNoise {
        PairNoise {
            left: self.left / 2.0,
            right: self.right / 2.0,
            stride: 1,
            ..self
        }
    }
}

/// [`disparity_probed`] on a pair whose statistics are known (`seen`, of the whole pair when this is
/// a crop of it).
pub fn disparity_probed_in(
    left: &Gray,
    right: &Gray,
    seen: PairNoise,
    params: &Params,
    cancel: &AtomicBool,
    wanted: &[Vec<usize>],
) -> Result<(Disparity, Timings, Vec<Vec<Probe>>), Cancelled> {
    let shape = params.shape();
    let levels = pyramid::levels_shaped(left.width, left.height, params.count, seen.faint, shape);
    // The paths are the whole pair's, at every level.
    let params = &Params {
        paths: params.paths.for_pair(seen.clarity, seen.stride),
        ..*params
    };
    level((left, right), seen, params, levels, cancel, wanted)
}

/// One level of the pyramid: the level above it first when `above` levels remain, then this
/// level's pair matched over the windows that level's map gives ([`pyramid::Prior`]), or over
/// the whole range at the coarsest level.
fn level(
    (left, right): (&Gray, &Gray),
    seen: PairNoise,
    params: &Params,
    above: usize,
    cancel: &AtomicBool,
    wanted: &[Vec<usize>],
) -> Result<(Disparity, Timings, Vec<Vec<Probe>>), Cancelled> {
    let (w, h) = (left.width, left.height);
    let checkpoint = || {
        if cancel.load(Ordering::Relaxed) {
            Err(Cancelled)
        } else {
            Ok(())
        }
    };
    let mut timings = Timings::default();
    let prior = if above > 0 {
        let started = Instant::now();
        let (l2, r2) = rayon::join(|| pyramid::halve(left), || pyramid::halve(right));
        timings.cost += started.elapsed();
        let (min, count) = pyramid::halve_range(params.min_disparity, params.count);
        let coarse = Params {
            min_disparity: min,
            count,
            speckle_size: params.speckle_size / 4,
            fill: false,
            plane: false,
            ..*params
        };
        let (map, t, _) = level((&l2, &r2), seen.halved(), &coarse, above - 1, cancel, &[])?;
        timings.add(t);
        let started = Instant::now();
        let prior = pyramid::Prior::shaped(&map, min, params.shape());
        timings.refine += started.elapsed();
        Some(prior)
    } else {
        None
    };
    let window = match prior {
        Some(_) => params.shape().window.min(cost::stride(params.count)),
        None => cost::stride(params.count),
    };
    let stripes = stripes::stripes(h, stripes::rows(w, window, prior.is_some()));
    // Each stripe writes its kept rows' disparities and variances in place.
    let mut data = vec![f32::NAN; w * h];
    let mut variance = vec![f32::NAN; w * h];
    let mut outputs = Vec::with_capacity(stripes.len());
    let (mut data_rest, mut variance_rest) = (&mut data[..], &mut variance[..]);
    for (kept, _) in &stripes {
        let (d, dr) = data_rest.split_at_mut(kept.len() * w);
        let (v, vr) = variance_rest.split_at_mut(kept.len() * w);
        outputs.push((d, v));
        (data_rest, variance_rest) = (dr, vr);
    }
    let pair = Seen {
        images: (left, right),
        noise: seen,
    };
    let started = Instant::now();
    let matched: Vec<Result<Stripe, Cancelled>> = stripes
        .par_iter()
        .zip(outputs)
        .map(|((kept, context), out)| {
            let probe = Probing { wanted, rows: kept };
            match_stripe(pair, context, params, prior.as_ref(), probe, out, cancel)
        })
        .collect();
    let stripes_time = started.elapsed();
    let mut summed = Timings::default();
    let mut probes = Vec::with_capacity(wanted.len());
    for stripe in matched {
        let (t, found) = stripe?;
        probes.extend(found);
        summed.add(t);
    }
    drop(prior);
    timings.add(summed.sharing(stripes_time));
    timings.paths = Some(params.paths);
    checkpoint()?;

    let started = Instant::now();
    let (mut data, std, filled, blank) = filters::finish(data, variance, w, left, params);
    let min = params.min_disparity as f32;
    data.iter_mut().for_each(|d| *d += min);
    timings.refine += started.elapsed();
    probes.truncate(wanted.len());
    Ok((
        Disparity {
            width: w,
            height: h,
            data,
            std,
            filled,
            blank,
        },
        timings,
        probes,
    ))
}

impl Timings {
    /// Adds another's stage times to these.
    fn add(&mut self, other: Timings) {
        self.cost += other.cost;
        self.aggregate += other.aggregate;
        self.refine += other.refine;
        self.paths = self.paths.or(other.paths);
        self.cells = self.cells.saturating_add(other.cells);
    }

    /// `wall`, shared between the stages in proportion to these (summed) times.
    pub(crate) fn sharing(self, wall: Duration) -> Timings {
        let total = (self.cost + self.aggregate + self.refine).as_secs_f64();
        if total <= 0.0 {
            return Timings {
                cost: wall,
                ..Timings::default()
            };
        }
        let share = |d: Duration| wall.mul_f64(d.as_secs_f64() / total);
        Timings {
            cost: share(self.cost),
            aggregate: share(self.aggregate),
            refine: share(self.refine),
            paths: self.paths,
            cells: self.cells,
        }
    }
}

/// A matched stripe's stage times and its rows' probes (its kept rows' disparities and their
/// winners' variances, [`sigma::winner_variance`], are written in place).
type Stripe = (Timings, Vec<Vec<Probe>>);

/// A level's pair and what was measured of the whole pair's noise ([`PairNoise`]).
#[derive(Clone, Copy)]
struct Seen<'a> {
    images: (&'a Gray, &'a Gray),
    noise: PairNoise,
}

/// The pixels to probe (`wanted[y]`, by image row) and the rows a stripe keeps.
#[derive(Clone, Copy)]
struct Probing<'a> {
    wanted: &'a [Vec<usize>],
    rows: &'a Range<usize>,
}

/// One stripe: its `context` rows' census signatures (the left image's centres guiding P2
/// across edges, so that noise is not taken for edges) and 8-bit grey levels, the cost volume
/// over each pixel's window (from `prior`, or the whole range) and the two passes over those
/// rows, the winners and the left-right check of its `kept` rows (disparities as indices into
/// the range). The features are made here, a stripe at a time, so that no image's signatures
/// are held whole.
fn match_stripe(
    Seen {
        images: (left, right),
        noise: seen,
    }: Seen,
    context: &Range<usize>,
    params: &Params,
    prior: Option<&pyramid::Prior>,
    probing: Probing,
    (out, variance): (&mut [f32], &mut [f32]),
    cancel: &AtomicBool,
) -> Result<Stripe, Cancelled> {
    let kept = probing.rows;
    let w = left.width;
    let stride = seen.stride;
    let range = (params.min_disparity, params.count);
    let mut timings = Timings::default();
    let started = Instant::now();
    // On this thread alone: see census::transform_rows.
    let (cl, guide) = census::transform_rows(left, seen.left, stride, context.clone());
    let (cr, _) = census::transform_rows(right, seen.right, stride, context.clone());
    let pixels = context.start * w..context.end * w;
    let (gl, gr) = (
        cost::levels_of(&left.data[pixels.clone()]),
        cost::levels_of(&right.data[pixels]),
    );
    let windows = match prior {
        Some(prior) => prior.windows(context.clone(), w, range),
        None => cost::Windows::full(context.len() * w, params.count),
    };
    let census = (&cl[..], &cr[..]);
    let grey = (&gl[..], &gr[..]);
    let made = cost::Rows {
        census,
        grey,
        width: w,
        range,
    };
    // The cells are made a row at a time where the passes read them (twice with 8 paths):
    // making a row again costs less than storing the volume and reading it back.
    let volume = cost::made(made, context.len(), windows);
    timings.cost = started.elapsed();
    timings.cells = volume.windows.cells();
    if cancel.load(Ordering::Relaxed) {
        return Err(Cancelled);
    }

    let started = Instant::now();
    let mut probes = vec![Vec::new(); kept.len()];
    let mut choosing = Duration::ZERO;
    let first = kept.start - context.start;
    sgm::aggregate(
        &volume,
        &guide,
        params.penalties,
        params.paths,
        cancel,
        &mut |y, totals| {
            if !(first..first + kept.len()).contains(&y) {
                return;
            }
            let chose = Instant::now();
            let windows = refine::RowWindows::of(&volume.windows, y, w);
            let mut won = refine::winners(
                totals,
                windows,
                params.count,
                params.uniqueness,
                params.subpixel,
            );
            if let Some(xs) = probing.wanted.get(kept.start + y - first) {
                probes[y - first] = xs
                    .iter()
                    .map(|&x| refine::probe(totals, windows, census, (x, y), params, &won.right))
                    .collect();
            }
            let row = (y - first) * w..(y - first + 1) * w;
            let off = refine::disagreements(&won.left, &won.right);
            sigma::winner_variances(
                &won.left,
                &won.cues,
                &off,
                stride,
                &mut variance[row.clone()],
            );
            if let Some(tolerance) = params.lr_tolerance {
                refine::left_right(&mut won.left, &off, tolerance);
            }
            out[row].copy_from_slice(&won.left);
            choosing += chose.elapsed();
        },
    )?;
    timings.aggregate = started.elapsed().saturating_sub(choosing);
    timings.refine = choosing;
    Ok((timings, probes))
}
