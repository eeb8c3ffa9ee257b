//! Integration tests: each starts the real server on 127.0.0.1:0 and talks to it over a real
//! socket with reqwest.

mod batch;
mod board;
mod calibrate;
mod calibrate_initial;
mod calibration;
mod calibration_check;
mod chart;
mod charuco;
mod command_line;
mod damaged;
mod depth_map;
mod depth_stream;
mod disparity;
mod distance;
mod errors;
mod faults;
mod fixtures;
mod heavy;
mod helpers;
mod matching;
mod openapi;
mod operations;
mod planning;
mod protection;
mod recording;
mod recording_bags;
mod recording_faults;
mod rectify;
mod rigs;
mod ros_answers;
mod scale;
mod svg;
mod table;
mod tokens;
mod web;
