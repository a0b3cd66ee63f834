//! Enums of a few named choices (the solver scheme, the cut mode) spelled as strings in
//! files, on the command line and in JSON: one macro writes the name table, `Display`,
//! `FromStr` and serde for each, so every choice parses and fails the same way.

/// Implements `ALL`, `name`, `Display`, `FromStr`, `Serialize` and `Deserialize` for a
/// fieldless enum from its variants and their names; `$what` names the choice in
/// errors ("unknown solver `x` (allowed: …)").
macro_rules! named_enum {
    ($ty:ident, $what:literal, [$($variant:ident => $name:literal),+ $(,)?]) => {
        impl $ty {
            /// Every choice, in the order the documentation lists them.
            pub const ALL: [$ty; [$($name),+].len()] = [$($ty::$variant),+];

            /// The choice's name in files, on the command line and in JSON.
            pub fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name,)+
                }
            }

            /// The names, quoted and comma-separated, as error messages list them.
            fn names() -> String {
                [$(concat!("\"", $name, "\"")),+].join(", ")
            }
        }

        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl std::str::FromStr for $ty {
            type Err = String;

            fn from_str(s: &str) -> std::result::Result<Self, String> {
                $ty::ALL
                    .into_iter()
                    .find(|m| m.name() == s)
                    .ok_or_else(|| format!(concat!("unknown ", $what, " `{}` (allowed: {})"), s, $ty::names()))
            }
        }

        impl serde::Serialize for $ty {
            fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
                s.serialize_str(self.name())
            }
        }

        impl<'de> serde::Deserialize<'de> for $ty {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
                struct Name;
                impl serde::de::Visitor<'_> for Name {
                    type Value = $ty;
                    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                        write!(f, "one of the strings {}", $ty::names())
                    }
                    fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<$ty, E> {
                        v.parse().map_err(E::custom)
                    }
                }
                // (`any` in text formats: a bare RON identifier then fails with the list of
                // quoted names instead of a bare "expected string"; binary formats, which
                // cannot tell what comes next, read a string)
                if d.is_human_readable() {
                    d.deserialize_any(Name)
                } else {
                    d.deserialize_str(Name)
                }
            }
        }
    };
}

pub(crate) use named_enum;
