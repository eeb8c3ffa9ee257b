//! The binary's command line as a user types it: the server's options before or after a
//! subcommand, sizes with units on every size flag, and a refused value from the environment
//! named by its variable.

use std::process::Command;

fn binary() -> Command {
    Command::new(env!("CARGO_BIN_EXE_stereo-distance"))
}

/// The server's options are taken after a subcommand as before it: `depth-map …
/// --heavy-memory-budget 512MiB` runs (here over empty folders), `healthcheck --port P` probes
/// that port, and `serve --help` lists them.
#[test]
fn the_servers_options_go_before_or_after_a_subcommand() {
    let dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("command-line");
    for side in ["left", "right"] {
        std::fs::create_dir_all(dir.join(side)).unwrap();
    }
    let run = binary()
        .args(["depth-map", "--left"])
        .arg(dir.join("left"))
        .arg("--right")
        .arg(dir.join("right"))
        .arg("--out")
        .arg(dir.join("out"))
        .args(["--heavy-memory-budget", "512MiB", "--body-limit", "64KiB"])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(0), "{said}");
    assert!(said.contains("wrote 0 of 0 pairs"), "{said}");

    let probe = binary()
        .args(["healthcheck", "--port", "1", "--timeout", "200ms"])
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&probe.stderr);
    assert_eq!(probe.status.code(), Some(1), "{said}");
    assert!(said.contains("unhealthy") && said.contains(":1"), "{said}");

    let help = binary().args(["serve", "--help"]).output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in [
        "--port",
        "--body-limit <SIZE>",
        "--heavy-memory-budget",
        "--api-tokens-file",
    ] {
        assert!(help.contains(flag), "{flag} not in serve --help:\n{help}");
    }
}

/// `depth-map --help` lists the command's own options and the server's that a run in process
/// uses (its memory budget and image limit, the logs), not the ports, origins, timeouts and
/// tokens of a server; those are still taken after `depth-map` (above).
#[test]
fn depth_map_help_shows_its_own_options() {
    let help = binary().args(["depth-map", "--help"]).output().unwrap();
    assert_eq!(help.status.code(), Some(0));
    let help = String::from_utf8_lossy(&help.stdout);
    for flag in [
        "--calibration <FILE>",
        "--max-disparity",
        "--server <URL>",
        "--heavy-memory-budget",
        "--max-image-pixels",
    ] {
        assert!(
            help.contains(flag),
            "{flag} not in depth-map --help:\n{help}"
        );
    }
    for flag in [
        "--port",
        "--host",
        "--cors-allowed-origins",
        "--api-tokens",
        "--request-timeout",
        "--body-limit",
        "--max-streams",
    ] {
        assert!(!help.contains(flag), "{flag} in depth-map --help:\n{help}");
    }
}

/// Every size flag takes units (`--body-limit 64KiB` as `--heavy-body-limit 32MiB`), and a
/// value refused from the environment names its variable, not only the flag.
#[test]
fn sizes_take_units_and_the_environment_is_named() {
    let help = binary()
        .args([
            "--body-limit",
            "64KiB",
            "--batch-body-limit",
            "2MiB",
            "--help",
        ])
        .output()
        .unwrap();
    assert_eq!(help.status.code(), Some(0));
    let refused = binary()
        .args(["--port", "0"])
        .env("BODY_LIMIT", "a lot")
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(refused.status.code(), Some(2), "{said}");
    assert!(
        said.contains("--body-limit") && said.contains("environment variable BODY_LIMIT"),
        "{said}"
    );
    let flag = binary()
        .args(["--body-limit", "a lot"])
        .env("BODY_LIMIT", "64KiB")
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&flag.stderr);
    assert!(!said.contains("environment variable"), "{said}");
}
