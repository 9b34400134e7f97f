//! The ingest library against a real PostgreSQL cluster (and, for the
//! worker, a real mosquitto), both started by the test kit; without them
//! the tests skip with a note (`.ci/run` requires them).

mod database;
mod worker;
