//! Settings chosen from a fixed list of names (solver, integrator, certification policy,
//! eigensolver, gradient mode): one spelling per value, shared by scene files (serde), the
//! command line and Python.

/// A setting whose values are a fixed list of names.
///
/// The name is the scene file's spelling (snake_case); front ends list [`Choice::ALL`] with
/// [`Choice::name`] and parse with [`Choice::from_name`], so no second spelling exists.
///
/// ```
/// use diffsoft::base::Choice;
/// use diffsoft::solver::Integrator;
///
/// assert_eq!(Integrator::from_name("bdf2"), Some(Integrator::Bdf2));
/// assert_eq!(Integrator::ImplicitEuler.name(), "implicit_euler");
/// ```
pub trait Choice: Sized + Copy + PartialEq + 'static {
    /// Every value, in the order the documentation lists them.
    const ALL: &'static [Self];

    /// The value's one spelling.
    fn name(self) -> &'static str;

    /// The value named `s` (its spelling, or the same with `-` for `_`, which older command
    /// lines used).
    fn from_name(s: &str) -> Option<Self> {
        Self::ALL
            .iter()
            .copied()
            .find(|c| c.name() == s || c.name().replace('_', "-") == s)
    }

    /// The names, comma-separated (for messages).
    fn names() -> String {
        Self::ALL.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ")
    }
}

/// Implements [`Choice`] for a fieldless enum: `choice!(Type { Variant => "name", ... })`.
#[macro_export]
macro_rules! choice {
    ($t:ty { $($v:ident => $n:literal),+ $(,)? }) => {
        impl $crate::base::Choice for $t {
            const ALL: &'static [Self] = &[$(<$t>::$v),+];
            fn name(self) -> &'static str {
                match self {
                    $(<$t>::$v => $n),+
                }
            }
        }
    };
}
