//! Library enums on the command line: their names become clap's possible values (with each
//! value's help), parsed back through [`Named`] (the library does not depend on clap).

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use trilab::conditioning::MethodChoice;
use trilab::encoding::{Method, Traversal};
use trilab::named::Named;

/// A value parser for the library enum `T`: `#[arg(long, value_parser = choice::<T>())]`.
pub fn choice<T: Named + Clone + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::ALL.iter().map(|v| PossibleValue::new(v.name()).help(v.help().trim_end_matches('.'))))
        .map(|s| T::from_name(&s).expect("clap accepted one of the possible values"))
}

/// `--traversal`: each traversal's possible value with its help and what it has kernels for
/// (layouts, access paths, kinds), read from the compiled variants' support matrix.
pub fn traversal_choice() -> impl TypedValueParser<Value = Traversal> {
    PossibleValuesParser::new(Traversal::ALL.iter().map(|t| {
        let help = format!("{} Kernels: {}", t.help(), trilab::encoding::traversal_support(*t));
        PossibleValue::new(t.name()).help(help)
    }))
    .map(|s| Traversal::from_name(&s).expect("clap accepted one of the possible values"))
}

/// `--method`: a method's name or `auto` (clap's list of them is hidden: [`method_help`] lists
/// them with their titles in the help itself, so `-h` shows them too).
pub fn method_choice() -> impl TypedValueParser<Value = MethodChoice> {
    let names = std::iter::once("auto").chain(Method::ALL.iter().map(|m| m.name()));
    PossibleValuesParser::new(names.map(PossibleValue::new))
        .map(|s| s.parse::<MethodChoice>().expect("clap accepted one of the possible values"))
}

/// `what`, then one line per method (`name  title`, from the registry), then `auto`.
pub fn method_help(what: &str) -> String {
    let width = Method::ALL.iter().map(|m| m.name().len()).max().unwrap_or(0).max(4);
    let mut s = format!("{what}\n");
    for m in Method::ALL {
        s += &format!("  {:width$}  {}\n", m.name(), m.title());
    }
    s += &format!(
        "  {:width$}  the cheapest that meets the default accuracy target on this scene (see `trilab analyze`);\n  {:width$}  what it picked and why goes to stderr and the JSON",
        "auto", ""
    );
    s
}
