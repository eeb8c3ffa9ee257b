//! Integration tests: each starts the real server on 127.0.0.1:0 and talks to it over a real
//! socket with reqwest.

mod chart;
mod distance;
mod errors;
mod helpers;
mod openapi;
mod operations;
mod protection;
mod table;
