//! The command-line tool's larger subcommands, one module each (the binary's own code; the
//! library is `diffsoft`). `main.rs` parses the command line and dispatches.

pub(crate) mod choice;
pub(crate) mod files;
pub(crate) mod grad;
pub(crate) mod numbers;
pub(crate) mod overrides;
pub(crate) mod simulate;
pub(crate) mod tradeoff;

/// What every subcommand module uses.
mod prelude {
    pub(crate) use std::path::{Path, PathBuf};

    pub(crate) use anyhow::{bail, Context, Result};
}

/// An error's message with its causes, one line: `context: cause: cause`, leaving out a cause
/// whose text the message already holds (an error whose own text includes its source would
/// otherwise say it twice).
pub(crate) fn message(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    // One line: a cause that spans lines (a parser's excerpt) is joined.
    out.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_cause_already_in_the_message_is_not_repeated() {
        #[derive(Debug)]
        struct Outer {
            source: std::io::Error,
        }
        impl std::fmt::Display for Outer {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                write!(f, "scene.json: invalid input: {}", self.source)
            }
        }
        impl std::error::Error for Outer {
            fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
                Some(&self.source)
            }
        }
        let e = anyhow::Error::from(Outer {
            source: std::io::Error::other("body 'c': Poisson ratio 0.6"),
        });
        assert_eq!(
            super::message(&e),
            "scene.json: invalid input: body 'c': Poisson ratio 0.6"
        );
        let e = anyhow::anyhow!("inner").context("outer");
        assert_eq!(super::message(&e), "outer: inner");
    }
}
