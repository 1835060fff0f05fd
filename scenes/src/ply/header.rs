//! The PLY header: the element / property model and header parsing.

use std::path::Path;

use super::input::{Input, LineRead};
use super::{excerpt, ferr};
use crate::SceneError;

/// Longest header line accepted (a binary file without newlines fails fast).
const MAX_HEADER_LINE: usize = 64 * 1024;
/// Largest header accepted.
const MAX_HEADER_BYTES: u64 = 1 << 20;

// ---------------------------------------------------------------------------------------------
// Header model
// ---------------------------------------------------------------------------------------------

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    pub(super) fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
    pub(super) fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
    /// The type's name in a header (the classic names).
    pub(super) fn name(self) -> &'static str {
        match self {
            Scalar::I8 => "char",
            Scalar::U8 => "uchar",
            Scalar::I16 => "short",
            Scalar::U16 => "ushort",
            Scalar::I32 => "int",
            Scalar::U32 => "uint",
            Scalar::F32 => "float",
            Scalar::F64 => "double",
        }
    }
    /// The smallest and largest value of an integer type (`None` for floats).
    pub(super) fn int_range(self) -> Option<(i64, i64)> {
        Some(match self {
            Scalar::I8 => (i8::MIN.into(), i8::MAX.into()),
            Scalar::U8 => (0, u8::MAX.into()),
            Scalar::I16 => (i16::MIN.into(), i16::MAX.into()),
            Scalar::U16 => (0, u16::MAX.into()),
            Scalar::I32 => (i32::MIN.into(), i32::MAX.into()),
            Scalar::U32 => (0, u32::MAX.into()),
            Scalar::F32 | Scalar::F64 => return None,
        })
    }
}

#[derive(Debug, Clone, Copy)]
pub(super) enum PropType {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
pub(super) struct Property {
    pub(super) name: String,
    pub(super) ty: PropType,
}

#[derive(Debug)]
pub(super) struct Element {
    pub(super) name: String,
    pub(super) count: u64,
    pub(super) props: Vec<Property>,
}

impl Element {
    /// Record size in bytes when no property is a list.
    pub(super) fn fixed_size(&self) -> Option<usize> {
        self.props.iter().try_fold(0usize, |acc, p| match p.ty {
            PropType::Scalar(s) => Some(acc + s.size()),
            PropType::List { .. } => None,
        })
    }
    /// Smallest possible record in bytes (lists empty), at least 1.
    pub(super) fn min_record_bytes(&self, ascii: bool) -> u64 {
        let b: usize = if ascii {
            // Every value needs at least one character and one separator.
            2 * self.props.len()
        } else {
            self.props
                .iter()
                .map(|p| match p.ty {
                    PropType::Scalar(s) => s.size(),
                    PropType::List { count, .. } => count.size(),
                })
                .sum()
        };
        b.max(1) as u64
    }
    pub(super) fn find(&self, name: &str) -> Option<usize> {
        self.props.iter().position(|p| p.name == name)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Encoding {
    Ascii,
    Binary { big_endian: bool },
}

#[derive(Debug)]
pub(super) struct Header {
    pub(super) encoding: Encoding,
    pub(super) elements: Vec<Element>,
    /// Number of header lines (the first body line is `lines + 1`).
    pub(super) lines: u64,
}

// ---------------------------------------------------------------------------------------------
// Header parsing
// ---------------------------------------------------------------------------------------------

/// Parses the header at the start of `input` (of the file at `path`), up to and including
/// its `end_header` line.
pub(super) fn parse_header(input: &mut Input, path: &Path) -> Result<Header, SceneError> {
    let mut line_no: u64 = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line_no += 1;
        let text = next_header_line(input, path, line_no)?;
        if line_no == 1 {
            check_magic(path, text)?;
            continue;
        }
        let mut toks = text.split_ascii_whitespace();
        let Some(keyword) = toks.next() else {
            continue; // blank line
        };
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                let enc = parse_format(toks, path, line_no)?;
                if encoding.is_some() {
                    return Err(ferr(path, format!("line {line_no}: second 'format' line")));
                }
                encoding = Some(enc);
            }
            "element" => elements.push(parse_element(toks, path, line_no)?),
            "property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(ferr(
                        path,
                        format!("line {line_no}: 'property' before any 'element'"),
                    ));
                };
                el.props.push(parse_property(toks, text, path, line_no)?);
            }
            "end_header" => break,
            other => {
                return Err(ferr(
                    path,
                    format!(
                        "line {line_no}: unexpected '{}' in the header (expected format, element, \
                         property, comment, obj_info or end_header; is end_header missing?)",
                        excerpt(other)
                    ),
                ));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(ferr(path, "the header has no 'format' line"));
    };
    Ok(Header {
        encoding,
        elements,
        lines: line_no,
    })
}

/// Reads header line `line_no` as text (without its line end), within the header's limits
/// of bytes and line length.
fn next_header_line<'i>(
    input: &'i mut Input,
    path: &Path,
    line_no: u64,
) -> Result<&'i str, SceneError> {
    if input.position() > MAX_HEADER_BYTES {
        return Err(ferr(
            path,
            format!("no end_header line within the first {MAX_HEADER_BYTES} bytes"),
        ));
    }
    let raw = match input
        .next_line_range(MAX_HEADER_LINE)
        .map_err(|e| SceneError::io(path, e))?
    {
        LineRead::Line(r) => &input.buf[r],
        LineRead::Eof if line_no == 1 => {
            return Err(ferr(
                path,
                "not a PLY file: the file is empty (no 'ply' magic)",
            ));
        }
        LineRead::Eof => {
            return Err(ferr(
                path,
                format!("the header ends at line {line_no} without an end_header line"),
            ));
        }
        LineRead::TooLong if line_no == 1 => {
            return Err(ferr(path, "not a PLY file: line 1 is not the 'ply' magic"));
        }
        LineRead::TooLong => {
            return Err(ferr(
                path,
                format!(
                    "line {line_no}: header line longer than {MAX_HEADER_LINE} bytes \
                     (missing end_header?)"
                ),
            ));
        }
    };
    let Ok(text) = std::str::from_utf8(raw) else {
        return Err(if line_no == 1 {
            ferr(path, "not a PLY file: line 1 is not the 'ply' magic")
        } else {
            ferr(
                path,
                format!("line {line_no}: the header contains non-text bytes (missing end_header?)"),
            )
        });
    };
    Ok(text.trim_end_matches('\r'))
}

/// Line 1 must be the `ply` magic.
fn check_magic(path: &Path, text: &str) -> Result<(), SceneError> {
    if text.trim() != "ply" {
        return Err(ferr(
            path,
            format!(
                "not a PLY file: line 1 is '{}', expected the 'ply' magic",
                excerpt(text)
            ),
        ));
    }
    Ok(())
}

/// The encoding of a `format NAME VERSION` line (`toks`: the tokens after `format`).
fn parse_format<'t>(
    mut toks: impl Iterator<Item = &'t str>,
    path: &Path,
    line_no: u64,
) -> Result<Encoding, SceneError> {
    let name = toks.next().unwrap_or("");
    let version = toks.next().unwrap_or("");
    let enc = match name {
        "ascii" => Encoding::Ascii,
        "binary_little_endian" => Encoding::Binary { big_endian: false },
        "binary_big_endian" => Encoding::Binary { big_endian: true },
        other => {
            return Err(ferr(
                path,
                format!(
                    "line {line_no}: unknown format '{}' (expected ascii, \
                     binary_little_endian or binary_big_endian)",
                    excerpt(other)
                ),
            ));
        }
    };
    if !(version == "1.0" || version == "1") {
        return Err(ferr(
            path,
            format!(
                "line {line_no}: unsupported format version '{}' (expected 1.0)",
                excerpt(version)
            ),
        ));
    }
    Ok(enc)
}

/// The element of an `element NAME COUNT` line (`toks`: the tokens after `element`), with no
/// properties yet.
fn parse_element<'t>(
    mut toks: impl Iterator<Item = &'t str>,
    path: &Path,
    line_no: u64,
) -> Result<Element, SceneError> {
    let (Some(name), Some(count)) = (toks.next(), toks.next()) else {
        return Err(ferr(
            path,
            format!("line {line_no}: expected 'element NAME COUNT'"),
        ));
    };
    let Ok(count) = count.parse::<u64>() else {
        return Err(ferr(
            path,
            format!(
                "line {line_no}: element '{name}' has count '{}', expected a \
                 non-negative integer",
                excerpt(count)
            ),
        ));
    };
    Ok(Element {
        name: name.to_owned(),
        count,
        props: Vec::new(),
    })
}

/// The property of a `property TYPE NAME` or `property list COUNT_TYPE ITEM_TYPE NAME` line
/// (`toks`: the tokens after `property`; `text`: the whole line).
fn parse_property<'t>(
    toks: impl Iterator<Item = &'t str>,
    text: &str,
    path: &Path,
    line_no: u64,
) -> Result<Property, SceneError> {
    let toks: Vec<&str> = toks.collect();
    let bad_type = |t: &str| {
        ferr(
            path,
            format!(
                "line {line_no}: unknown property type '{}' (expected char, uchar, \
                 short, ushort, int, uint, float, double or their int8…float64 names)",
                excerpt(t)
            ),
        )
    };
    Ok(match toks.as_slice() {
        ["list", ct, it, name] => {
            let count = Scalar::parse(ct).ok_or_else(|| bad_type(ct))?;
            let item = Scalar::parse(it).ok_or_else(|| bad_type(it))?;
            if !count.is_integer() {
                return Err(ferr(
                    path,
                    format!(
                        "line {line_no}: list '{name}' has count type '{ct}', which \
                         is not an integer type"
                    ),
                ));
            }
            Property {
                name: (*name).to_owned(),
                ty: PropType::List { count, item },
            }
        }
        [ty, name] if *ty != "list" => Property {
            name: (*name).to_owned(),
            ty: PropType::Scalar(Scalar::parse(ty).ok_or_else(|| bad_type(ty))?),
        },
        _ => {
            return Err(ferr(
                path,
                format!(
                    "line {line_no}: expected 'property TYPE NAME' or 'property list \
                     COUNT_TYPE ITEM_TYPE NAME', found '{}'",
                    excerpt(text)
                ),
            ));
        }
    })
}
