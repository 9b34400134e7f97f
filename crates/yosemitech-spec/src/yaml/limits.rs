//! How much YAML one file may hold, and how much work finding its
//! problems may take: hostile input is refused early and cheaply.

/// Most YAML nodes (scalars, sequences, mappings) one file may hold, aliases
/// expanded. The real specs have a few thousand.
pub const MAX_YAML_NODES: usize = 100_000;
/// Deepest nesting of YAML collections. The spec language needs eight.
pub const MAX_YAML_DEPTH: usize = 32;
/// Most alias (`*name`) uses in one file.
pub const MAX_YAML_ALIASES: usize = 1_000;
/// Most nodes aliases may copy in one file: stops exponential "billion
/// laughs" expansion long before it costs time or memory.
pub const MAX_ALIAS_REPLAY: usize = 50_000;

/// Most problems reported for one file's YAML.
pub(super) const MAX_YAML_PROBLEMS: usize = 20;
/// Most times one file is parsed (again) to find its problems: bounds the
/// work on hostile input to this many parses of at most the whole file.
pub(super) const MAX_YAML_PARSES: usize = 2 * MAX_YAML_PROBLEMS;

/// Most times the lines after a quote or bracket never closed are read
/// again as if it closed on its line.
pub(super) const MAX_LAYOUT_RESETS: usize = 4;
