//! The database's schema, created and migrated by `ingest` itself.
//!
//! Each entry of [`MIGRATIONS`] takes the schema from the version before it
//! to its own; `yosemitech_schema` holds the version in force. Migrating
//! takes an advisory lock, so workers that start together migrate once.
//! A database at a version this build does not know is refused rather
//! than written to. `docs/postgres.md` describes the tables.

use postgres::Transaction;

/// The statements of each schema version, oldest first: version `n` is
/// `MIGRATIONS[n - 1]`. Never edit one that has shipped; add the next.
pub const MIGRATIONS: &[&str] = &[
    // Version 1.
    "
    CREATE TABLE stations (
        station    text PRIMARY KEY,
        first_seen timestamptz NOT NULL DEFAULT now(),
        last_seen  timestamptz NOT NULL DEFAULT now()
    );

    -- A probe as the readings show it: another serial number, firmware or
    -- calibration at the same label is another row.
    CREATE TABLE probes (
        probe_id       bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
        station        text NOT NULL REFERENCES stations (station),
        label          text NOT NULL,
        bus            text,
        sensor         text NOT NULL,
        address        smallint NOT NULL,
        serial_number  text,
        firmware       text,
        calibration_id bigint,
        first_seen     timestamptz NOT NULL DEFAULT now(),
        CONSTRAINT probes_identity UNIQUE NULLS NOT DISTINCT
            (station, label, bus, sensor, address, serial_number, firmware, calibration_id)
    );

    -- One row per reading, its identity the station's: (station, reading_id).
    -- Partitioned by month of taken_at; readings_default takes what no
    -- month's partition does (none, as ingest creates a month's partition
    -- before its first reading).
    CREATE TABLE readings (
        station      text NOT NULL,
        reading_id   bigint NOT NULL,
        taken_at     timestamptz NOT NULL,
        probe_id     bigint NOT NULL REFERENCES probes (probe_id),
        measurements jsonb NOT NULL,
        retries      integer NOT NULL,
        error        text,
        stored_at    timestamptz NOT NULL DEFAULT now(),
        PRIMARY KEY (station, reading_id, taken_at)
    ) PARTITION BY RANGE (taken_at);
    CREATE TABLE readings_default PARTITION OF readings DEFAULT;

    -- One probe over a time range; the latest reading of every probe.
    CREATE INDEX readings_by_probe ON readings (probe_id, taken_at DESC);

    CREATE VIEW latest_readings AS
        SELECT DISTINCT ON (r.probe_id) p.station, p.label, p.sensor, p.serial_number, r.probe_id,
               r.reading_id, r.taken_at, r.measurements, r.retries, r.error
        FROM readings r JOIN probes p USING (probe_id)
        ORDER BY r.probe_id, r.taken_at DESC;

    -- A message that is not a reading (not JSON, another schema): kept, not
    -- lost, and kept once however often it is delivered.
    CREATE TABLE rejected_messages (
        id          bigint GENERATED ALWAYS AS IDENTITY PRIMARY KEY,
        topic       text NOT NULL,
        payload     bytea NOT NULL,
        reason      text NOT NULL,
        received_at timestamptz NOT NULL DEFAULT now()
    );
    CREATE UNIQUE INDEX rejected_messages_once ON rejected_messages (topic, md5(payload));
    ",
];

/// The schema version this build writes.
pub fn current_version() -> i32 {
    i32::try_from(MIGRATIONS.len()).unwrap_or(i32::MAX)
}

/// Why the database's schema cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SchemaError {
    /// A later version of ingest migrated it.
    #[error("the database has schema version {found}; this ingest knows versions up to {known}: upgrade it")]
    Newer {
        /// The database's version.
        found: i32,
        /// The newest this build knows.
        known: i32,
    },
    /// The server refused a statement.
    #[error("cannot migrate the schema: {0}")]
    Postgres(#[from] postgres::Error),
}

/// Brings the schema to [`current_version`], in `tx`; returns the version
/// found before (0 for an empty database).
pub fn migrate(tx: &mut Transaction<'_>) -> Result<i32, SchemaError> {
    // One migrator at a time; the others find the work done.
    tx.execute("SELECT pg_advisory_xact_lock(hashtext('yosemitech_schema'))", &[])?;
    tx.batch_execute("CREATE TABLE IF NOT EXISTS yosemitech_schema (version integer NOT NULL)")?;
    let found: i32 = match tx.query_opt("SELECT version FROM yosemitech_schema", &[])? {
        Some(row) => row.get(0),
        None => {
            tx.execute("INSERT INTO yosemitech_schema (version) VALUES (0)", &[])?;
            0
        }
    };
    let known = current_version();
    if found > known {
        return Err(SchemaError::Newer { found, known });
    }
    let from = usize::try_from(found).unwrap_or(0);
    for statements in MIGRATIONS.iter().skip(from) {
        tx.batch_execute(statements)?;
    }
    tx.execute("UPDATE yosemitech_schema SET version = $1", &[&known])?;
    Ok(found)
}
