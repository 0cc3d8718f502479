//! Close reasons: every way the server ends a session, with the WebSocket close code it sends
//! and whether a client should reconnect. `docs/protocol.md` lists them.

/// Why the server closed a session.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CloseReason {
    /// The server is shutting down or restarting: reconnect and resume.
    Draining,
    /// A frame did not decode, a text frame arrived, or a text frame was not UTF-8.
    Malformed,
    /// A message exceeded the server's size limit.
    TooLarge,
    /// The hello's protocol version is not the server's.
    Version,
    /// A message that is not allowed at this point (a second hello, a pose before the hello,
    /// an acknowledgement of a delta never sent), or a frame that breaks RFC 6455 (reserved
    /// bits or opcodes, an unmasked frame, a fragmented or oversized control frame, a stray
    /// continuation frame).
    Protocol,
    /// A camera with NaN or infinite values, or far outside the terrain.
    BadCamera,
    /// Lens, tau or budget out of range.
    BadParams,
    /// A resume snapshot that is malformed, too large, or for another terrain.
    BadSnapshot,
    /// No message for longer than the idle timeout.
    Idle,
    /// The server holds its maximum number of sessions.
    ServerFull,
    /// The client's address holds its maximum number of sessions.
    TooManyFromAddress,
    /// The client does not read what it is sent.
    SlowReader,
    /// A server fault; the session can be resumed.
    Internal,
    /// The server is starting and has no terrain yet: retry shortly.
    NotReady,
    /// The session's cut reached the server's limit of interior nodes: raise tau or shrink
    /// the viewport.
    CutLimit,
}

impl CloseReason {
    /// Every reason, for documentation and tests.
    pub const ALL: [CloseReason; 15] = [
        CloseReason::Draining,
        CloseReason::Malformed,
        CloseReason::TooLarge,
        CloseReason::Version,
        CloseReason::Protocol,
        CloseReason::BadCamera,
        CloseReason::BadParams,
        CloseReason::BadSnapshot,
        CloseReason::Idle,
        CloseReason::ServerFull,
        CloseReason::TooManyFromAddress,
        CloseReason::SlowReader,
        CloseReason::Internal,
        CloseReason::NotReady,
        CloseReason::CutLimit,
    ];

    /// The WebSocket close code (RFC 6455 section 7.4; 4000-4999 are this protocol's own).
    pub fn code(self) -> u16 {
        match self {
            CloseReason::Draining => 1012,
            CloseReason::Malformed => 1007,
            CloseReason::TooLarge => 1009,
            CloseReason::Version => 4001,
            CloseReason::Protocol => 1002,
            CloseReason::BadCamera => 4002,
            CloseReason::BadParams => 4003,
            CloseReason::BadSnapshot => 4004,
            CloseReason::Idle => 4005,
            CloseReason::ServerFull => 1013,
            CloseReason::TooManyFromAddress => 4006,
            CloseReason::SlowReader => 4007,
            CloseReason::Internal => 1011,
            CloseReason::NotReady => 4008,
            CloseReason::CutLimit => 4009,
        }
    }

    /// The reason for a close code, if it is one of this protocol's.
    pub fn from_code(code: u16) -> Option<CloseReason> {
        CloseReason::ALL.into_iter().find(|r| r.code() == code)
    }

    /// A short stable name, used as the metrics label and the prefix of the close text.
    pub fn name(self) -> &'static str {
        match self {
            CloseReason::Draining => "draining",
            CloseReason::Malformed => "malformed",
            CloseReason::TooLarge => "too_large",
            CloseReason::Version => "version",
            CloseReason::Protocol => "protocol",
            CloseReason::BadCamera => "bad_camera",
            CloseReason::BadParams => "bad_params",
            CloseReason::BadSnapshot => "bad_snapshot",
            CloseReason::Idle => "idle",
            CloseReason::ServerFull => "server_full",
            CloseReason::TooManyFromAddress => "too_many_from_address",
            CloseReason::SlowReader => "slow_reader",
            CloseReason::Internal => "internal",
            CloseReason::NotReady => "not_ready",
            CloseReason::CutLimit => "cut_limit",
        }
    }

    /// Whether a client should reconnect (and resume) after this close. The others mean the
    /// client must change what it sends.
    pub fn retry(self) -> bool {
        matches!(
            self,
            CloseReason::Draining
                | CloseReason::ServerFull
                | CloseReason::TooManyFromAddress
                | CloseReason::Idle
                | CloseReason::SlowReader
                | CloseReason::Internal
                | CloseReason::NotReady
        )
    }

    /// The close frame's text: `name: detail`, cut to the 123 bytes a close frame can carry.
    pub fn text(self, detail: &str) -> String {
        let mut s = format!("{}: {detail}", self.name());
        if s.len() > 123 {
            let mut end = 123;
            while !s.is_char_boundary(end) {
                end -= 1;
            }
            s.truncate(end);
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_and_names_are_unique_and_round_trip() {
        for (i, a) in CloseReason::ALL.iter().enumerate() {
            assert_eq!(CloseReason::from_code(a.code()), Some(*a));
            for b in &CloseReason::ALL[i + 1..] {
                assert_ne!(a.code(), b.code());
                assert_ne!(a.name(), b.name());
            }
        }
    }

    #[test]
    fn text_fits_a_close_frame() {
        let t = CloseReason::BadCamera.text(&"é".repeat(200));
        assert!(t.len() <= 123 && t.starts_with("bad_camera: "));
    }
}
