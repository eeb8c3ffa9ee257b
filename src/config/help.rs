//! What the command line's `--help` shows: the server's options are global (taken after a
//! subcommand as before it), and `depth-map --help` hides those a run in process does not use.

use super::Cli;

/// The server's options a `depth-map` run in process uses, shown in its `--help`.
const IN_PROCESS: [&str; 4] = [
    "log_format",
    "log_level",
    "heavy_memory_budget",
    "max_image_pixels",
];

impl Cli {
    /// The command line. The server's options are global, so that they are taken after a
    /// subcommand as before it; for a `depth-map` run (`depth_map`) its `--help` shows only
    /// those a run in process uses ([`IN_PROCESS`]) and hides the rest, which `serve --help`
    /// lists.
    pub fn command_for(depth_map: bool) -> clap::Command {
        let command = <Self as clap::CommandFactory>::command();
        if !depth_map {
            return command;
        }
        let hidden: Vec<clap::Id> = command
            .get_arguments()
            .filter(|a| a.is_global_set() && !IN_PROCESS.contains(&a.get_id().as_str()))
            .map(|a| a.get_id().clone())
            .collect();
        hidden
            .iter()
            .fold(command, |command, id| command.mut_arg(id, |a| a.hide(true)))
    }
}
