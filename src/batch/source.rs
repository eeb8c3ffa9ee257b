//! What a run reads: a recording's pairs (two folders, one folder, or a ROS bag), the files
//! or frames left out and why, and the rig's parts (a `--calibration` file, or a bag's
//! CameraInfo); and the feed that hands the pairs to the workers, a bag's read on a thread of
//! its own a few pairs ahead of them.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use stereo_ros::msg::Header;

use super::pairing::{self, FramePair, file_name};
use super::work::{Input, Pair, Work};
use super::{bag, preflight};
use crate::config::DepthMapArgs;

/// The longest message read from a bag: a 16-bit RGBA frame at the largest size the service
/// takes would be longer, but no camera records one.
const BAG_RECORD_LIMIT: usize = 512 << 20;

/// The pairs still to do: a list, or a bag's, read as the workers take them.
pub enum Feed {
    List(Mutex<VecDeque<Work>>),
    Bag(tokio::sync::Mutex<tokio::sync::mpsc::Receiver<Work>>),
}

impl Feed {
    pub async fn next(&self) -> Option<Work> {
        match self {
            Feed::List(list) => list.lock().ok().and_then(|mut q| q.pop_front()),
            Feed::Bag(receiver) => receiver.lock().await.recv().await,
        }
    }
}

/// What the run reads: its pairs, the files or frames left out (what, why), the rig's parts
/// (name, file name, bytes) with the names their faults take, and the frames' size where
/// the recording states it.
pub struct Recording {
    pub pairs: Pairs,
    pub unpaired: Vec<(String, String)>,
    pub rig: Option<preflight::Rig>,
    /// A line about the pairing, for a bag.
    pub about: Option<String>,
    /// Why a bag could not be read to its end.
    pub cut: Option<String>,
    pub namespace: String,
}

pub enum Pairs {
    Files(Vec<FramePair>),
    Bag(Box<bag::Survey>),
}

impl Pairs {
    pub fn names(&self) -> Vec<String> {
        match self {
            Pairs::Files(pairs) => pairs.iter().map(|p| p.name.clone()).collect(),
            Pairs::Bag(survey) => survey.pairs.iter().map(|p| p.name.clone()).collect(),
        }
    }
}

/// The recording the arguments name: its pairs and what was left out, and the rig.
pub fn recording(args: &DepthMapArgs) -> Result<Recording, String> {
    let calibration = match &args.calibration {
        Some(path) => {
            let bytes = std::fs::read(path)
                .map_err(|e| format!("cannot read the calibration {}: {e}", path.display()))?;
            let mut parts = vec![("calibration".to_owned(), Some(file_name(path)), bytes)];
            if let Some(unit) = &args.calibration_unit {
                parts.push((
                    "calibration_unit".to_owned(),
                    None,
                    unit.clone().into_bytes(),
                ));
            }
            Some(preflight::Rig {
                parts,
                labels: ["--calibration".to_owned(), "--calibration".to_owned()],
                size: None,
            })
        }
        None => None,
    };
    if let Some(path) = &args.bag {
        let skew = args
            .max_skew
            .map(|d| d.as_nanos().min(i64::MAX as u128) as i64);
        let topics = [args.left_topic.as_deref(), args.right_topic.as_deref()];
        let (path, part) = match (
            args.part,
            stereo_ros::bag::recordings(path).map_err(|e| e.to_string())?,
        ) {
            (Some(part), Some(list)) if list.len() == part.count => {
                (list[part.index].clone(), None)
            }
            (Some(part), Some(list)) => {
                return Err(format!(
                    "--part {}/{}: {} holds {} recordings; give --part I/{} (one a pod), or \
                     one recording",
                    part.index,
                    part.count,
                    path.display(),
                    list.len(),
                    list.len()
                ));
            }
            (part, _) => (path.clone(), part),
        };
        let path = &path;
        let mut survey = bag::survey(path, topics, skew, BAG_RECORD_LIMIT)?;
        if let Some(part) = part {
            let n = survey.pairs.len();
            let range = part.index * n / part.count..(part.index + 1) * n / part.count;
            survey.pairs = survey.pairs[range].to_vec();
        }
        let rig = match calibration {
            Some(rig) => Some(rig),
            None => {
                let topics = [survey.left.as_str(), survey.right.as_str()];
                let [left, right] = bag::calibration(&survey.info, topics)?;
                let labels = survey
                    .info
                    .clone()
                    .map(|i| i.map(|(t, _)| t).unwrap_or_default());
                let size = survey.info[0]
                    .as_ref()
                    .map(|(_, i)| (i.width, i.height))
                    .filter(|&(w, h)| w > 0 && h > 0);
                Some(preflight::Rig {
                    parts: vec![
                        (
                            "calibration".to_owned(),
                            Some("left.yaml".to_owned()),
                            left.into_bytes(),
                        ),
                        (
                            "right_calibration".to_owned(),
                            Some("right.yaml".to_owned()),
                            right.into_bytes(),
                        ),
                        ("calibration_format".to_owned(), None, b"ros".to_vec()),
                    ],
                    labels,
                    size,
                })
            }
        };
        let about = format!(
            "{} {}: {} pairs{} of {} and {} by stamp, within {:.1} ms (--max-skew)",
            survey.bag.kind(),
            path.display(),
            survey.pairs.len(),
            part.map_or(String::new(), |p| format!(
                " (part {}/{})",
                p.index, p.count
            )),
            survey.left,
            survey.right,
            survey.max_skew_ns as f64 / 1e6
        );
        let unpaired = survey
            .orphans
            .iter()
            .map(|o| (o.what.clone(), o.reason.clone()))
            .collect();
        return Ok(Recording {
            namespace: args
                .out_namespace
                .clone()
                .unwrap_or_else(|| bag::namespace_of(&survey.left, &survey.right)),
            unpaired,
            rig,
            about: Some(about),
            cut: survey.cut.clone(),
            pairs: Pairs::Bag(Box::new(survey)),
        });
    }
    let (pairs, unpaired) = match (&args.frames, &args.left, &args.right) {
        (Some(folder), _, _) => {
            let (files, others) = images_in(folder)?;
            let (pairs, mut unpaired) = pairing::pair_one_folder(&files);
            unpaired.extend(others);
            (pairs, unpaired)
        }
        (None, Some(left), Some(right)) => {
            let (l, mut others) = images_in(left)?;
            let (r, more) = images_in(right)?;
            others.extend(more);
            let (pairs, mut unpaired) = pairing::pair_two_folders(&l, &r);
            unpaired.extend(others);
            (pairs, unpaired)
        }
        _ => return Err("give --left and --right, --frames, or --bag".to_owned()),
    };
    let mut unpaired: Vec<(String, String)> = unpaired
        .into_iter()
        .map(|u| (u.path.display().to_string(), u.reason))
        .collect();
    unpaired.sort();
    let rig = calibration.map(|mut rig| {
        rig.size = pairs.iter().find_map(|p| {
            let bytes = std::fs::read(&p.left).ok()?;
            stereo_core::vision::decode::dimensions(&bytes).ok()
        });
        rig
    });
    Ok(Recording {
        pairs: Pairs::Files(pairs),
        unpaired,
        rig,
        about: None,
        cut: None,
        namespace: args
            .out_namespace
            .clone()
            .unwrap_or_else(|| bag::DEFAULT_NAMESPACE.to_owned()),
    })
}

/// The pairs to do (those not `done`): a list of files, or a bag's pairs read on a thread of
/// their own, a few ahead of the workers (so the bag is never in memory).
pub fn feed(pairs: Pairs, done: &std::collections::HashSet<String>, jobs: usize) -> Feed {
    match pairs {
        Pairs::Files(pairs) => Feed::List(Mutex::new(
            pairs
                .into_iter()
                .enumerate()
                .filter(|(_, p)| !done.contains(&p.name))
                .enumerate()
                .map(|(seq, (k, p))| Work {
                    pair: Pair {
                        seq,
                        name: p.name,
                        names: [p.left.display().to_string(), p.right.display().to_string()],
                    },
                    input: Input::Files(p.left, p.right, folder_header(k)),
                })
                .collect(),
        )),
        Pairs::Bag(survey) => {
            let (sender, receiver) = tokio::sync::mpsc::channel(jobs * 2);
            let todo: Vec<bag::StampPair> = survey
                .pairs
                .iter()
                .filter(|p| !done.contains(&p.name))
                .cloned()
                .collect();
            std::thread::spawn(move || {
                let mut frames = bag::Frames::new(&survey, BAG_RECORD_LIMIT);
                for (seq, pair) in todo.into_iter().enumerate() {
                    let names = [
                        format!("{} at {}", survey.left, pair.name),
                        format!("{} at {}", survey.right, bag::stamp_name(pair.right_stamp)),
                    ];
                    let input = match frames.read(&pair) {
                        Ok([l, r]) => match (bag::frame(&l), bag::frame(&r)) {
                            (Ok((header, l)), Ok((_, r))) => {
                                Input::Frames(Box::new([l, r]), header)
                            }
                            (Err(e), _) => Input::Broken(format!("{}: {e}", names[0])),
                            (_, Err(e)) => Input::Broken(format!("{}: {e}", names[1])),
                        },
                        Err(e) => Input::Broken(e),
                    };
                    let work = Work {
                        pair: Pair {
                            seq,
                            name: pair.name.clone(),
                            names,
                        },
                        input,
                    };
                    if sender.blocking_send(work).is_err() {
                        break;
                    }
                }
            });
            Feed::Bag(tokio::sync::Mutex::new(receiver))
        }
    }
}

/// A folder's pairs have no stamps: in an MCAP output they are stamped 0.1 s apart from
/// the epoch, in their order, in the frame `left_camera`.
const FOLDER_FRAME_NS: i64 = 100_000_000;

fn folder_header(k: usize) -> Header {
    Header {
        stamp_ns: k as i64 * FOLDER_FRAME_NS,
        frame_id: "left_camera".to_owned(),
    }
}

/// The folder's PNG and JPEG files, and its other files as unpaired (folders and hidden files
/// left alone).
fn images_in(folder: &Path) -> Result<(Vec<PathBuf>, Vec<pairing::Unpaired>), String> {
    let entries = std::fs::read_dir(folder)
        .map_err(|e| format!("cannot read the folder {}: {e}", folder.display()))?;
    let (mut images, mut others) = (Vec::new(), Vec::new());
    for entry in entries.flatten() {
        let path = entry.path();
        if !path.is_file() || file_name(&path).starts_with('.') {
            continue;
        }
        if pairing::is_image(&path) {
            images.push(path);
        } else {
            others.push(pairing::Unpaired {
                path,
                reason: "not a PNG or JPEG".to_owned(),
            });
        }
    }
    Ok((images, others))
}
