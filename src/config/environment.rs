//! A refused option's value said with where it came from: clap names the flag, but a value set
//! in the environment (a Kubernetes manifest, a shell profile) is found by its variable.

use std::ffi::OsString;

/// `error`, clap's refusal of `args` for `command`, naming the environment variable the refused
/// value came from when the flag was not on the command line.
pub fn named(error: clap::Error, args: &[OsString], command: &clap::Command) -> clap::Error {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if !matches!(
        error.kind(),
        ErrorKind::InvalidValue | ErrorKind::ValueValidation
    ) {
        return error;
    }
    let Some(ContextValue::String(arg)) = error.get(ContextKind::InvalidArg) else {
        return error;
    };
    let Some(long) = arg
        .split_whitespace()
        .next()
        .and_then(|a| a.strip_prefix("--"))
    else {
        return error;
    };
    let given = args.iter().any(|a| {
        a.to_str()
            .is_some_and(|a| a == format!("--{long}") || a.starts_with(&format!("--{long}=")))
    });
    let env = std::iter::once(command)
        .chain(command.get_subcommands())
        .flat_map(|c| c.get_arguments())
        .find(|a| a.get_long() == Some(long))
        .and_then(|a| a.get_env())
        .map(|e| e.to_string_lossy().into_owned());
    let Some(env) = env.filter(|e| !given && std::env::var_os(e).is_some()) else {
        return error;
    };
    let rendered = error.render().to_string();
    let rendered = rendered.strip_prefix("error: ").unwrap_or(&rendered);
    let (first, rest) = rendered.split_once('\n').unwrap_or((rendered, ""));
    clap::Error::raw(
        error.kind(),
        format!("{first} (from the environment variable {env}, as --{long} was not given)\n{rest}"),
    )
}
