//! The commands `--sensor` and `--command` leave to decode as, checked
//! against the loaded sensors.

use yosemitech_spec::suggest::closest;

use crate::catalog::Catalog;
use crate::commands::decode::DecodeArgs;
use crate::error::{CliError, Result};
use crate::explain::Commands;

/// Every loaded command, with the choice of `args` (a sensor, a command) checked.
pub(super) fn commands<'c>(catalog: &'c Catalog, args: &DecodeArgs) -> Result<Commands<'c>> {
    let mut commands = Commands::new(catalog.entries().iter().map(|e| &*e.sensor));
    if let Some(name) = &args.sensor {
        commands.sensor = Some(catalog.entry(name)?.sensor.name.as_str());
    }
    let wanted = args.command.as_ref().map(|n| n.replace('-', "_"));
    if let (Some(name), Some(wanted)) = (&args.command, &wanted)
        && !commands.of_chosen_sensors().any(|c| c.command.name == *wanted)
    {
        let names: Vec<&str> = commands.of_chosen_sensors().map(|c| c.command.name.as_str()).collect();
        let e = CliError::usage(format!("no loaded sensor has a command `{name}`"));
        return Err(match closest(wanted, &names) {
            Some(best) => e.hint(format!("did you mean `{best}`? `yosemitech list` shows every command")),
            None => e.hint("`yosemitech list` shows every command"),
        });
    }
    commands.command = wanted;
    Ok(commands)
}
