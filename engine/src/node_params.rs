//! Typed parameters of a node kind: one declaration gives the struct a node reads and the
//! [`Field`](crate::spec::Field) table the compiler checks, `spindlelab nodes`, the schema
//! and the docs show, so a default is written in one place.
//!
//! ```text
//! node_params! {
//!     /// Parameters of `frf.gap`.
//!     pub struct GapParams<'a> {
//!         band: opt &'a [f64] = (T::QuantityList(D::FREQUENCY), "[low, high] Hz to compare"),
//!         noise: def &'a str = (T::Choice(&["coherence", "declared"]), "coherence", "where the noise comes from"),
//!         cutting: req &'a str = (T::Entity(EntityKind::Cutting), "the cut"),
//!     }
//! }
//! let p = GapParams::read(ctx.params)?;   // p.band: Option<&[f64]>, p.noise: &str
//! spec.params = GapParams::fields();
//! ```
//!
//! A field several kinds share is declared once as a `Field` constant and named instead of
//! the arguments: `interface: def &'a str = INTERFACE`.
//!
//! `req` and `def` fields are always present once a recipe is checked (a default is filled in
//! by the checker, parsed like user input), so they read as plain values; `opt` fields read
//! as `Option`. Reading names the parameter if the node is handed unchecked parameters.

use crate::spec::{ParamValue, Params};
use std::path::Path;

/// A Rust value one checked parameter reads as.
pub trait ParamRead<'a>: Sized {
    /// The value of `name` in `p`, if present and of this type.
    fn read(p: &'a Params, name: &str) -> Option<Self>;
}

impl ParamRead<'_> for f64 {
    fn read(p: &Params, name: &str) -> Option<Self> {
        p.f64(name)
    }
}

impl ParamRead<'_> for i64 {
    fn read(p: &Params, name: &str) -> Option<Self> {
        p.int(name)
    }
}

/// A count or index: an integer field whose bounds keep it non-negative.
impl ParamRead<'_> for usize {
    fn read(p: &Params, name: &str) -> Option<Self> {
        p.int(name).and_then(|i| usize::try_from(i).ok())
    }
}

impl ParamRead<'_> for u64 {
    fn read(p: &Params, name: &str) -> Option<Self> {
        p.int(name).and_then(|i| u64::try_from(i).ok())
    }
}

impl ParamRead<'_> for bool {
    fn read(p: &Params, name: &str) -> Option<Self> {
        p.bool(name)
    }
}

/// Text, a choice word or an entity name.
impl<'a> ParamRead<'a> for &'a str {
    fn read(p: &'a Params, name: &str) -> Option<Self> {
        p.text(name)
    }
}

/// A list of SI quantities.
impl<'a> ParamRead<'a> for &'a [f64] {
    fn read(p: &'a Params, name: &str) -> Option<Self> {
        p.list(name)
    }
}

/// A file, resolved against the recipe's folder.
impl<'a> ParamRead<'a> for &'a Path {
    fn read(p: &'a Params, name: &str) -> Option<Self> {
        p.file(name)
    }
}

impl<'a> ParamRead<'a> for &'a Params {
    fn read(p: &'a Params, name: &str) -> Option<Self> {
        p.object(name)
    }
}

impl<'a> ParamRead<'a> for &'a [Params] {
    fn read(p: &'a Params, name: &str) -> Option<Self> {
        p.objects(name)
    }
}

/// The raw checked value, for a parameter several types may take.
impl<'a> ParamRead<'a> for &'a ParamValue {
    fn read(p: &'a Params, name: &str) -> Option<Self> {
        p.get(name)
    }
}

/// Declares a node kind's typed parameters and their [`Field`](crate::spec::Field) table;
/// see the [module docs](self).
#[macro_export]
macro_rules! node_params {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident<$lt:lifetime> {
            $( $field:ident : $how:ident $ty:ty = $rhs:tt ),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[allow(non_snake_case)]
        #[derive(Debug, Clone, Copy)]
        $vis struct $name<$lt> {
            $( pub $field: $crate::node_params!(@type $how $ty), )*
            _params: ::std::marker::PhantomData<&$lt ()>,
        }

        impl<$lt> $name<$lt> {
            /// The field table: what the compiler checks and `spindlelab nodes` shows.
            pub fn fields() -> ::std::vec::Vec<$crate::spec::Field> {
                ::std::vec![ $( $crate::node_params!(@field $field, $how, $rhs), )* ]
            }

            /// Reads checked parameters.
            pub fn read(p: &$lt $crate::spec::Params) -> ::std::result::Result<Self, $crate::node::NodeError> {
                Ok($name {
                    $( $field: $crate::node_params!(@read $how $ty, p, stringify!($field)), )*
                    _params: ::std::marker::PhantomData,
                })
            }
        }
    };
    (@field $field:ident, $how:ident, ( $($arg:expr),+ $(,)? )) => {
        $crate::spec::Field::$how(stringify!($field), $($arg),+)
    };
    // A field several kinds share, declared once as a `Field` constant of the same name.
    (@field $field:ident, $how:ident, $shared:ident) => {{
        let f: $crate::spec::Field = $shared;
        debug_assert_eq!(f.name, stringify!($field), "shared field `{}` declared as `{}`", f.name, stringify!($field));
        debug_assert_eq!(
            (f.required, f.default.is_some()),
            $crate::node_params!(@how $how),
            "shared field `{}` is not `{}`",
            f.name,
            stringify!($how)
        );
        f
    }};
    (@how req) => { (true, false) };
    (@how opt) => { (false, false) };
    (@how def) => { (false, true) };
    (@type opt $ty:ty) => { ::std::option::Option<$ty> };
    (@type req $ty:ty) => { $ty };
    (@type def $ty:ty) => { $ty };
    (@read opt $ty:ty, $p:ident, $n:expr) => { <$ty as $crate::node_params::ParamRead>::read($p, $n) };
    (@read $how:ident $ty:ty, $p:ident, $n:expr) => {
        <$ty as $crate::node_params::ParamRead>::read($p, $n).ok_or_else(|| {
            $crate::node::NodeError::param($n, "missing or of the wrong type: the parameters were not checked against this node's fields")
        })?
    };
}

#[cfg(test)]
mod tests {
    use crate::spec::{FieldType as T, ParamValue, Params};
    use spindlelab_grammar::Dimension as D;

    const SHARED: crate::spec::Field = crate::spec::Field::def("teeth", T::Integer { min: 1, max: 64 }, "2", "teeth");

    node_params! {
        /// A node's parameters.
        struct Demo<'a> {
            band: opt &'a [f64] = (T::QuantityList(D::FREQUENCY), "[low, high] Hz"),
            noise: def &'a str = (T::Choice(&["coherence", "declared"]), "coherence", "where the noise comes from"),
            Ks: req f64 = (T::Quantity(D::PRESSURE), "specific cutting force"),
            teeth: def usize = SHARED,
        }
    }

    #[test]
    fn one_declaration_gives_the_field_table_and_the_typed_reader() {
        let f = Demo::fields();
        let names: Vec<_> = f.iter().map(|f| (f.name, f.required, f.default)).collect();
        assert_eq!(
            names,
            [
                ("band", false, None),
                ("noise", false, Some("coherence")),
                ("Ks", true, None),
                ("teeth", false, Some("2"))
            ]
        );
        let mut p = Params::default();
        p.values.insert("noise".into(), ParamValue::Text("declared".into()));
        p.values.insert("Ks".into(), ParamValue::Quantity { value: 2e9, dim: D::PRESSURE });
        p.values.insert("teeth".into(), ParamValue::Int(4));
        let d = Demo::read(&p).unwrap();
        assert_eq!((d.band, d.noise, d.Ks, d.teeth), (None, "declared", 2e9, 4));
        // A required field missing from unchecked parameters is named, not a panic.
        p.values.shift_remove("Ks");
        let e = Demo::read(&p).unwrap_err().to_string();
        assert!(e.contains("Ks"), "{e}");
    }
}
