//! The integration tests, one binary: each module was a test crate of its own; together they
//! link the program once.

mod common;

mod architecture;
mod audit_inputs;
mod audit_output;
mod case_model;
mod chatter_frequency;
mod cli_units_and_folders;
mod crib;
mod dev_cases;
mod diagnose;
mod diagnose_matrix;
mod diagnose_out_of_sample;
mod edges_cli;
mod edges_output;
mod edges_readers;
mod engine;
mod errors;
mod fit;
mod frf_low_lines;
mod fuzz;
mod guarantees;
mod impact_study;
mod import;
mod imported_recipes;
mod measured_set_fit;
mod measured_sets;
mod measurement;
mod measurement_sets;
mod modal_frf;
mod params;
mod plugins;
mod read_nodes;
mod registry;
mod report;
mod reuse;
mod scripts;
mod shards;
mod stability;
mod structure;
mod truth_simulator;
