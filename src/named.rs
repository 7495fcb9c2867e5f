//! Closed sets of named values: the library's option enums (methods, leaf policies, presets,
//! ...). Each has one name per value, used on the command line, in files and in messages, and
//! one line of help. The library parses and prints them with `FromStr`/`Display`; the command
//! line turns [`Named::ALL`] into its possible values (the library does not depend on clap).

/// A value of a closed set with a name and a line of help.
pub trait Named: Copy + Sized + 'static {
    /// Every value, in the order they are listed.
    const ALL: &'static [Self];

    /// The name on the command line and in files (kebab-case).
    fn name(self) -> &'static str;

    /// One line of help.
    fn help(self) -> &'static str;

    /// The value named `s` (ASCII case ignored).
    fn from_name(s: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|v| v.name().eq_ignore_ascii_case(s.trim()))
    }

    /// Every name, comma-separated (for messages).
    fn names() -> String {
        Self::ALL.iter().map(|v| v.name()).collect::<Vec<_>>().join(", ")
    }

    /// [`Named::from_name`], or an error naming what is accepted.
    fn parse_named(what: &str, s: &str) -> Result<Self, String> {
        Self::from_name(s).ok_or_else(|| format!("{what} `{s}`: expected one of {}", Self::names()))
    }
}

/// Defines an enum whose variants carry their names (`Variant = "name"`, or
/// `Variant = "name" (default)` for the `#[default]` one, also the type's `DEFAULT`: the one
/// place its default is spelled) and whose doc comments are their help; implements [`Named`],
/// `Display` (the name) and `FromStr` (by name, `$what` naming the set in errors).
macro_rules! named_enum {
    (
        $(#[$meta:meta])*
        $vis:vis enum $ty:ident : $what:literal {
            $(
                $(#[doc = $doc:literal])*
                $variant:ident = $name:literal $(($dflt:ident))?
            ),+ $(,)?
        }
    ) => {
        $(#[$meta])*
        $vis enum $ty {
            $(
                $(#[doc = $doc])*
                $(#[$dflt])?
                $variant
            ),+
        }

        impl $crate::named::Named for $ty {
            const ALL: &'static [$ty] = &[$($ty::$variant),+];

            fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }

            fn help(self) -> &'static str {
                match self {
                    $($ty::$variant => concat!($($doc),*).trim()),+
                }
            }
        }

        $($(
            impl $ty {
                #[doc = concat!("The ", $what, " taken when none is asked for (marked `(", stringify!($dflt), ")` where the values are listed).")]
                pub const DEFAULT: $ty = $ty::$variant;
            }
        )?)+

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str($crate::named::Named::name(*self))
            }
        }

        impl std::str::FromStr for $ty {
            type Err = String;

            fn from_str(s: &str) -> std::result::Result<Self, String> {
                <$ty as $crate::named::Named>::parse_named($what, s)
            }
        }
    };
}

pub(crate) use named_enum;

/// Whether `a` and `b` are the same string, in a `const` context (`str`'s `==` is not const):
/// the compile-time lookups of a default by its name (`Layout::named`, `Method::named`:
/// `crate::defaults`).
pub const fn same(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    if a.len() != b.len() {
        return false;
    }
    let mut i = 0;
    while i < a.len() {
        if a[i] != b[i] {
            return false;
        }
        i += 1;
    }
    true
}

#[cfg(test)]
mod tests {
    use super::Named;

    named_enum! {
        /// A test set.
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        enum Shape: "shape" {
            /// Round,
            /// on two lines.
            Circle = "circle" (default),
            Square = "square-ish",
        }
    }

    #[test]
    fn names_help_parse_and_print() {
        assert_eq!(Shape::ALL, &[Shape::Circle, Shape::Square]);
        assert_eq!(Shape::Square.to_string(), "square-ish");
        assert_eq!(Shape::Circle.help(), "Round, on two lines.");
        assert_eq!(Shape::Square.help(), "");
        assert_eq!("SQUARE-ish".parse::<Shape>(), Ok(Shape::Square));
        assert_eq!("triangle".parse::<Shape>(), Err("shape `triangle`: expected one of circle, square-ish".into()));
        assert_eq!(Shape::names(), "circle, square-ish");
        assert_eq!(Shape::default(), Shape::Circle);
        assert_eq!(Shape::DEFAULT, Shape::Circle);
        let same = crate::named::same;
        assert!(same("bvh2", "bvh2") && !same("bvh2", "bvh4") && !same("bvh", "bvh2"));
    }
}
