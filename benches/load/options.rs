//! The load benchmark's command line.

use std::{path::PathBuf, time::Duration};

pub const SERVICE_BIN: &str = env!("CARGO_BIN_EXE_stereo-distance");

pub const USAGE: &str = "\
usage: cargo bench --bench load -- [options]
  --warmup DUR         warm-up before each measurement, not recorded (default 1s)
  --duration DUR       measured time per endpoint and concurrency (default 5s)
  --concurrency LIST   connections, comma-separated (default 1,16,64,256)
  --paced-connections N  connections for the half-saturation run (default 64)
  --starts N           process starts timed for start-up latency (default 20)
  --out FILE           also write the report to FILE
  --service-bin PATH   the service binary to measure (default: the one cargo built for the
                       bench, with the release profile); for profiling a build with symbols
  --compare NAME=PATH  also measure the service binary at PATH on /distance, in the same run
                       and against the same baseline, its rows named NAME (repeatable)
  --only TEXT          measure only the endpoints whose name contains TEXT (and the baseline)
";

/// The seed's example 1: f = 35 px, B = 150 mm, 800×600, x 400 / 350 → 105 mm.

#[derive(Debug, Clone)]
pub struct Options {
    pub warmup: Duration,
    pub duration: Duration,
    pub levels: Vec<usize>,
    pub paced_connections: usize,
    pub starts: usize,
    pub out: Option<PathBuf>,
    pub service_bin: PathBuf,
    pub compare: Vec<(String, PathBuf)>,
    pub only: Option<String>,
}

impl Options {
    pub fn parse(args: &[String]) -> Result<Self, String> {
        let mut options = Options {
            warmup: Duration::from_secs(1),
            duration: Duration::from_secs(5),
            levels: vec![1, 16, 64, 256],
            paced_connections: 64,
            starts: 20,
            out: None,
            service_bin: PathBuf::from(SERVICE_BIN),
            compare: Vec::new(),
            only: None,
        };
        let mut args = args.iter();
        while let Some(flag) = args.next() {
            // cargo passes `--bench` to every bench binary.
            if flag == "--bench" {
                continue;
            }
            let mut value = || {
                args.next()
                    .ok_or_else(|| format!("{flag} needs a value\n{USAGE}"))
            };
            match flag.as_str() {
                "--warmup" => options.warmup = duration(value()?)?,
                "--duration" => options.duration = duration(value()?)?,
                "--concurrency" => {
                    options.levels = value()?
                        .split(',')
                        .map(|n| count(n.trim()))
                        .collect::<Result<_, _>>()?
                }
                "--paced-connections" => options.paced_connections = count(value()?)?,
                "--starts" => options.starts = count(value()?)?,
                "--out" => options.out = Some(PathBuf::from(value()?)),
                "--service-bin" => options.service_bin = PathBuf::from(value()?),
                "--compare" => {
                    let text = value()?;
                    let (name, path) = text
                        .split_once('=')
                        .ok_or_else(|| format!("--compare takes NAME=PATH, got {text:?}"))?;
                    options.compare.push((name.to_owned(), PathBuf::from(path)));
                }
                "--only" => options.only = Some(value()?.clone()),
                "-h" | "--help" => return Err(USAGE.to_owned()),
                other => return Err(format!("unknown option {other}\n{USAGE}")),
            }
        }
        if options.duration.is_zero() {
            return Err("--duration must be more than 0".to_owned());
        }
        Ok(options)
    }
}

pub fn duration(text: &str) -> Result<Duration, String> {
    humantime::parse_duration(text).map_err(|error| format!("{text:?}: {error}"))
}

pub fn count(text: &str) -> Result<usize, String> {
    match text.parse::<usize>() {
        Ok(n) if n > 0 => Ok(n),
        _ => Err(format!("{text:?} is not a positive whole number")),
    }
}
