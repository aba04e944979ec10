//! `robocal man`: the manual pages, rendered from the command line's own definition by
//! clap_mangen, so that they say what `--help` says.

use super::Cli;
use anyhow::Result;
use clap::CommandFactory;
use std::path::Path;

/// Print robocal's page (roff) to standard output, or write one page per command and
/// subcommand into `out` (all or none).
pub fn run(out: Option<&Path>) -> Result<()> {
    let mut command = Cli::command().disable_help_subcommand(true);
    command.build();
    let Some(folder) = out else {
        clap_mangen::Man::new(command).render(&mut std::io::stdout().lock())?;
        return Ok(());
    };
    let mut pages = Vec::new();
    collect(command, &mut pages)?;
    let mut outputs = robocal::io::Outputs::new();
    outputs.add_folder(folder, &pages);
    outputs.commit()?;
    super::status(format_args!("wrote {} manual pages to {}", pages.len(), folder.display()));
    Ok(())
}

/// The pages of `command` and of each of its subcommands, depth first: `(file name, roff)`.
fn collect(command: clap::Command, pages: &mut Vec<(String, String)>) -> Result<()> {
    for sub in command.get_subcommands().filter(|s| !s.is_hide_set()) {
        collect(sub.clone(), pages)?;
    }
    let man = clap_mangen::Man::new(command);
    let mut roff = Vec::new();
    man.render(&mut roff)?;
    pages.push((man.get_filename(), String::from_utf8(roff)?));
    Ok(())
}
