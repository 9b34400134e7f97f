//! The `--postgres` connection (ingest, export): a connection string, the
//! password only from the environment, never from the command line.

use std::str::FromStr;

use crate::error::{CliError, Result};

/// The environment variable of the database password (libpq's own).
pub const DATABASE_PASSWORD_VAR: &str = "PGPASSWORD";

/// The database configuration: the connection string, the password from the environment.
pub fn database_config(conninfo: &str) -> Result<postgres::Config> {
    let mut config = postgres::Config::from_str(conninfo).map_err(|e| {
        CliError::usage(format!("--postgres: not a connection string: {e}"))
            .hint("write \"host=/run/postgresql dbname=fleet\" or postgresql://user@host/fleet")
    })?;
    if config.get_password().is_some() {
        return Err(CliError::usage("--postgres holds a password (anyone on the machine can read a command line)")
            .hint(format!("leave it out and set {DATABASE_PASSWORD_VAR}")));
    }
    if let Ok(password) = std::env::var(DATABASE_PASSWORD_VAR) {
        config.password(password);
    }
    Ok(config)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_password_on_the_command_line_is_refused() {
        assert!(database_config("host=/tmp dbname=fleet password=hunter2").is_err());
        assert!(database_config("postgresql://user:hunter2@host/fleet").is_err());
        assert!(database_config("host=/tmp dbname=fleet").is_ok());
        assert!(database_config("not a = = conninfo '").is_err());
    }
}
