//! A pair of the run, and what a worker says about it: the types the run, its sources and
//! its workers share.

use std::path::PathBuf;

use stereo_ros::msg::Header;

use super::engine::Frame;

/// One pair of the run: what it is called, and where its frames are (the two part ways
/// when a worker reads the frames).
pub struct Work {
    pub pair: Pair,
    pub input: Input,
}

/// What a pair is called: its place in the run, its name (its outputs') and its frames'
/// names (as its faults name them).
pub struct Pair {
    /// Its place in the run's order (an MCAP output writes the pairs in it).
    pub seq: usize,
    pub name: String,
    pub names: [String; 2],
}

/// Where a pair's frames are.
pub enum Input {
    /// Two files, and the header their messages take in an MCAP output.
    Files(PathBuf, PathBuf, Header),
    /// Two frames read from a bag, and the left one's header.
    Frames(Box<[Frame; 2]>, Header),
    /// A pair that could not be read, and why.
    Broken(String),
}

/// What a worker tells the run: that it waits to send a frame again, or how a pair ended
/// (with the service's warnings about it).
pub enum Event {
    Waiting(String),
    Done {
        seq: usize,
        name: String,
        warnings: Vec<String>,
        result: Result<(), Failure>,
    },
}

/// Why a pair made no map: the pair's own fault, or one that stops the run.
pub enum Failure {
    Pair(String),
    Run(String),
}
