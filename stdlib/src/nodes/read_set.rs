//! `read.frf_set`: every FRF of a UFF or CSV file as one measurement set.
//!
//! `read.frf` reads one FRF (and a sweep of it, one step instance per FRF); a modal test's FRFs
//! fitted together (`modal.fit_set`) need them as one value on one grid. The file enters the
//! cache key by its contents, as with the other readers.

use super::read::{FILE_DOC, FORMAT_DEFAULT, FORMAT_DOC, FORMATS, file_format, read_error};
use spindlelab_engine::formats::{self, FrfSelect};
use spindlelab_engine::node::{Node, NodeContext, NodeError, NodeSpec, Outputs, PortSpec};
use spindlelab_engine::node_params;
use spindlelab_engine::spec::FieldType as T;
use spindlelab_engine::value::{PortType, Value};
use std::path::Path;

node_params! {
    /// Parameters of `read.frf_set`.
    pub struct ReadFrfSetParams<'a> {
        file: req &'a Path = (T::File, FILE_DOC),
        format: def &'a str = (T::Choice(FORMATS), FORMAT_DEFAULT, FORMAT_DOC),
        direction: opt &'a str = (
            T::Choice(&["x", "y", "z"]),
            "keep only the FRFs whose response is in this direction",
        ),
        response: opt i64 = (
            T::Integer { min: 0, max: i64::MAX },
            "keep only the FRFs whose response node number is this",
        ),
        reference: opt i64 = (
            T::Integer { min: 0, max: i64::MAX },
            "keep only the FRFs whose reference (excitation) node number is this",
        ),
    }
}

/// `read.frf_set`: the FRFs of a file as one set.
pub struct ReadFrfSet {
    spec: NodeSpec,
}

impl Default for ReadFrfSet {
    fn default() -> Self {
        Self::new()
    }
}

impl ReadFrfSet {
    pub fn new() -> Self {
        ReadFrfSet {
            spec: NodeSpec {
                kind: "read.frf_set",
                version: 1,
                description: "Reads every FRF of a file as one measurement set: the UFF datasets 58/58b of function type 4, or each block of rows of a CSV FRF file (as an FRF set or a swept FRF output writes it), with their response and reference nodes and directions; units to SI. The FRFs must share one frequency grid and one unit; `response`, `reference` and `direction` narrow the set.",
                inputs: vec![],
                outputs: vec![PortSpec::new(
                    "set",
                    PortType::FrfSet,
                    "the FRFs, in file order, on their common grid (Hz) in SI units",
                )],
                params: ReadFrfSetParams::fields(),
            },
        }
    }
}

impl Node for ReadFrfSet {
    fn spec(&self) -> &NodeSpec {
        &self.spec
    }

    fn run(&self, ctx: &NodeContext) -> Result<Outputs, NodeError> {
        let p = ReadFrfSetParams::read(ctx.params)?;
        let format = file_format(p.file, p.format)?;
        let select = FrfSelect {
            dataset: None,
            direction: p.direction.map(str::to_string),
            response: p.response,
            reference: p.reference,
        };
        let loaded = formats::read_frf_set(p.file, format, &select).map_err(read_error)?;
        for note in loaded.notes {
            ctx.warn(note);
        }
        Ok([("set".to_string(), Value::FrfSet(loaded.value))].into_iter().collect())
    }
}
