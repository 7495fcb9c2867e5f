//! Library enums on the command line: their names become clap's possible values (with each
//! value's help), parsed back through [`Named`] (the library does not depend on clap).

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use trilab::named::Named;

/// A value parser for the library enum `T`: `#[arg(long, value_parser = choice::<T>())]`.
pub fn choice<T: Named + Clone + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::ALL.iter().map(|v| PossibleValue::new(v.name()).help(v.help().trim_end_matches('.'))))
        .map(|s| T::from_name(&s).expect("clap accepted one of the possible values"))
}
