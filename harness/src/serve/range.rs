//! The `Range` request header (RFC 9110 §14.2), one byte range per request.

/// What a request's `Range` header asks of a representation of `len` bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ranged {
    /// No usable range: the whole representation, `200 OK`.
    Full,
    /// Bytes `start..end`, `206 Partial Content`.
    Part {
        /// The first byte.
        start: u64,
        /// One past the last byte (`start < end ≤ len`).
        end: u64,
    },
    /// A valid range that selects no byte of it, `416 Range Not Satisfiable`.
    Unsatisfiable,
}

/// Answers `header` (the `Range` value, if any) for a representation of `len` bytes.
///
/// - `bytes=a-b` (`b` clamped to the last byte), `bytes=a-` (to the end), `bytes=-n` (the
///   last `n`); a first byte at or past the end, or a suffix of 0 bytes, is unsatisfiable;
/// - several ranges (`bytes=0-9,20-29`) are answered with the whole representation, which
///   RFC 9110 allows (a server may ignore `Range`): no client of ours asks for them, and a
///   multipart body is one more format to get wrong;
/// - a malformed value or another unit is ignored as the RFC requires: the whole
///   representation.
pub fn parse(header: Option<&str>, len: u64) -> Ranged {
    let Some(h) = header else {
        return Ranged::Full;
    };
    let Some((unit, spec)) = h.trim().split_once('=') else {
        return Ranged::Full;
    };
    if !unit.trim().eq_ignore_ascii_case("bytes") || spec.contains(',') {
        return Ranged::Full;
    }
    let Some((first, last)) = spec.trim().split_once('-') else {
        return Ranged::Full;
    };
    let number = |s: &str| -> Option<u64> {
        let s = s.trim();
        if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        // More digits than a u64 holds: past any file's end.
        Some(s.parse().unwrap_or(u64::MAX))
    };
    match (first.trim().is_empty(), number(first), number(last)) {
        // Suffix: the last n bytes.
        (true, _, Some(n)) => {
            if n == 0 || len == 0 {
                Ranged::Unsatisfiable
            } else {
                Ranged::Part {
                    start: len.saturating_sub(n),
                    end: len,
                }
            }
        }
        (false, Some(a), b) => {
            if !last.trim().is_empty() && b.is_none() {
                return Ranged::Full;
            }
            if let Some(b) = b
                && b < a
            {
                return Ranged::Full;
            }
            if a >= len {
                return Ranged::Unsatisfiable;
            }
            let end = b.map_or(len, |b| b.saturating_add(1).min(len));
            Ranged::Part { start: a, end }
        }
        _ => Ranged::Full,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn part(start: u64, end: u64) -> Ranged {
        Ranged::Part { start, end }
    }

    #[test]
    fn single_open_ended_and_suffix_ranges() {
        let p = |h: &str| parse(Some(h), 100);
        assert_eq!(p("bytes=0-9"), part(0, 10));
        assert_eq!(p("bytes=10-10"), part(10, 11));
        assert_eq!(p("bytes=90-"), part(90, 100));
        assert_eq!(p("bytes=95-200"), part(95, 100), "the last byte is clamped");
        assert_eq!(p("bytes=-10"), part(90, 100));
        assert_eq!(
            p("bytes=-1000"),
            part(0, 100),
            "a suffix longer than the file"
        );
        assert_eq!(p(" Bytes = 5 - 6 "), part(5, 7), "case and spaces");
        assert_eq!(p("bytes=99-99999999999999999999999"), part(99, 100));
    }

    #[test]
    fn ranges_past_the_end_are_unsatisfiable() {
        assert_eq!(parse(Some("bytes=100-"), 100), Ranged::Unsatisfiable);
        assert_eq!(parse(Some("bytes=100-200"), 100), Ranged::Unsatisfiable);
        assert_eq!(parse(Some("bytes=-0"), 100), Ranged::Unsatisfiable);
        assert_eq!(parse(Some("bytes=0-"), 0), Ranged::Unsatisfiable);
        assert_eq!(parse(Some("bytes=-5"), 0), Ranged::Unsatisfiable);
        assert_eq!(
            parse(Some("bytes=99999999999999999999999-"), 100),
            Ranged::Unsatisfiable
        );
    }

    #[test]
    fn absent_malformed_multiple_or_other_units_give_the_whole() {
        for h in [
            "bytes=9-0",
            "bytes=a-b",
            "bytes=1-x",
            "bytes=-",
            "bytes=",
            "bytes 0-9",
            "items=0-9",
            "bytes=0-9,20-29",
            "bytes=+1-5",
        ] {
            assert_eq!(parse(Some(h), 100), Ranged::Full, "{h}");
        }
        assert_eq!(parse(None, 100), Ranged::Full);
    }
}
