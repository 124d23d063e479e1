//! The commands, one module each: `main` parses the command line and hands each its arguments.

pub(crate) mod cache;
pub(crate) mod crib;
pub(crate) mod diagnose;
pub(crate) mod export;
pub(crate) mod import;
pub(crate) mod plugin;
pub(crate) mod recipe;
pub(crate) mod report;
pub(crate) mod run;
