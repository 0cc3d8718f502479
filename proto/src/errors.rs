//! Error reporting shared by the command lines of both ends.

/// An error and its causes on one line, each cause once: errors often repeat their source in
/// their own message, which printing the whole chain would show twice.
pub fn one_line(e: &(dyn std::error::Error + 'static)) -> String {
    let mut line = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        cause = c.source();
    }
    line
}

/// Whether the command lines' logs on stderr may carry ANSI colours: only on a terminal, and
/// not when `NO_COLOR` is set to anything non-empty (<https://no-color.org>).
pub fn log_colour() -> bool {
    use std::io::IsTerminal;
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("cannot open {0}: {1}")]
    struct Repeats(&'static str, #[source] std::io::Error);

    #[derive(Debug, thiserror::Error)]
    #[error("cannot start")]
    struct Outer(#[source] Repeats);

    #[test]
    fn each_cause_appears_once() {
        let io = std::io::Error::other("no such file");
        let e = Outer(Repeats("x.relief", io));
        assert_eq!(
            one_line(&e),
            "cannot start: cannot open x.relief: no such file"
        );
    }
}
