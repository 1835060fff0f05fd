//! Scalar decoding and generic records (ascii lines, variable-size binary records).

use std::io;
use std::path::Path;

use super::header::{Element, PropType, Scalar};
use super::input::{Input, LineRead};
use super::{excerpt, ferr};
use crate::SceneError;

// ---------------------------------------------------------------------------------------------
// Scalar decoding
// ---------------------------------------------------------------------------------------------

#[inline(always)]
fn bytes_at<const N: usize>(s: &[u8], off: usize) -> [u8; N] {
    let mut a = [0u8; N];
    if let Some(src) = s.get(off..off + N) {
        a.copy_from_slice(src);
    }
    a
}

macro_rules! rd {
    ($be:expr, $t:ty, $s:expr, $off:expr) => {{
        let b = bytes_at::<{ std::mem::size_of::<$t>() }>($s, $off);
        if $be {
            <$t>::from_be_bytes(b)
        } else {
            <$t>::from_le_bytes(b)
        }
    }};
}

/// The scalar of type `ty` at `s[off..]` as `f64`.
#[inline(always)]
pub(super) fn scalar_f64<const BE: bool>(s: &[u8], off: usize, ty: Scalar) -> f64 {
    match ty {
        Scalar::I8 => rd!(BE, i8, s, off) as f64,
        Scalar::U8 => rd!(BE, u8, s, off) as f64,
        Scalar::I16 => rd!(BE, i16, s, off) as f64,
        Scalar::U16 => rd!(BE, u16, s, off) as f64,
        Scalar::I32 => rd!(BE, i32, s, off) as f64,
        Scalar::U32 => rd!(BE, u32, s, off) as f64,
        Scalar::F32 => rd!(BE, f32, s, off) as f64,
        Scalar::F64 => rd!(BE, f64, s, off),
    }
}

/// An integer scalar as `i64`; floats are truncated (only integer types reach here for counts
/// and indices, which the header checks).
#[inline(always)]
fn scalar_i64<const BE: bool>(s: &[u8], off: usize, ty: Scalar) -> i64 {
    match ty {
        Scalar::I8 => rd!(BE, i8, s, off) as i64,
        Scalar::U8 => rd!(BE, u8, s, off) as i64,
        Scalar::I16 => rd!(BE, i16, s, off) as i64,
        Scalar::U16 => rd!(BE, u16, s, off) as i64,
        Scalar::I32 => rd!(BE, i32, s, off) as i64,
        Scalar::U32 => rd!(BE, u32, s, off) as i64,
        Scalar::F32 => rd!(BE, f32, s, off) as i64,
        Scalar::F64 => rd!(BE, f64, s, off) as i64,
    }
}

/// A colour channel value of type `ty` as 8 bits (see the module docs).
#[inline(always)]
pub(super) fn color_u8(v: f64, ty: Scalar) -> u8 {
    let x = match ty {
        // Already an integer in 0..=255: no rounding (and no libm call) on the common path.
        Scalar::U8 => return v as u8,
        Scalar::F32 | Scalar::F64 => v * 255.0,
        Scalar::I16 | Scalar::U16 => v / 257.0,
        Scalar::I8 | Scalar::I32 | Scalar::U32 => v,
    };
    // Round half up on the clamped (non-negative) value; NaN casts to 0.
    (x.clamp(0.0, 255.0) + 0.5) as u8
}

// ---------------------------------------------------------------------------------------------
// Generic records (ascii lines, variable-size binary records)
// ---------------------------------------------------------------------------------------------

/// Why a binary record could not be read.
pub(super) enum RecErr {
    Io(io::Error),
    /// The file ends inside property `prop`.
    Eof {
        prop: usize,
    },
    /// A negative list count.
    Negative {
        prop: usize,
        count: i64,
    },
    /// A list count larger than the rest of the file can hold.
    TooBig {
        prop: usize,
        count: i64,
        bytes: u64,
        left: u64,
    },
}

/// Reads one binary record of `el`: scalars into `values` (lists leave NaN), the items of list
/// property `list` (if any) into `items`.
pub(super) fn read_binary_record<const BE: bool>(
    input: &mut Input,
    el: &Element,
    values: &mut [f64],
    list: Option<usize>,
    items: &mut Vec<i64>,
) -> Result<(), RecErr> {
    for (k, p) in el.props.iter().enumerate() {
        match p.ty {
            PropType::Scalar(s) => {
                let b = input
                    .take(s.size())
                    .map_err(RecErr::Io)?
                    .ok_or(RecErr::Eof { prop: k })?;
                values[k] = scalar_f64::<BE>(b, 0, s);
            }
            PropType::List { count, item } => {
                let b = input
                    .take(count.size())
                    .map_err(RecErr::Io)?
                    .ok_or(RecErr::Eof { prop: k })?;
                let n = scalar_i64::<BE>(b, 0, count);
                if n < 0 {
                    return Err(RecErr::Negative { prop: k, count: n });
                }
                let bytes = (n as u64).saturating_mul(item.size() as u64);
                if bytes > input.remaining() {
                    return Err(RecErr::TooBig {
                        prop: k,
                        count: n,
                        bytes,
                        left: input.remaining(),
                    });
                }
                let bytes = bytes as usize;
                if Some(k) == list {
                    let b = input
                        .take(bytes)
                        .map_err(RecErr::Io)?
                        .ok_or(RecErr::Eof { prop: k })?;
                    items.clear();
                    items.extend(
                        (0..n as usize).map(|j| scalar_i64::<BE>(b, j * item.size(), item)),
                    );
                } else if !input.skip(bytes as u64).map_err(RecErr::Io)? {
                    return Err(RecErr::Eof { prop: k });
                }
                values[k] = f64::NAN;
            }
        }
    }
    Ok(())
}

pub(super) fn rec_err(path: &Path, el: &Element, i: u64, e: RecErr) -> SceneError {
    let what = |prop: usize| {
        el.props
            .get(prop)
            .map_or_else(String::new, |p| format!(", property '{}'", p.name))
    };
    match e {
        RecErr::Io(e) => SceneError::io(path, e),
        RecErr::Eof { prop } => ferr(
            path,
            format!(
                "unexpected end of file in {} {i} of {}{}",
                el.name,
                el.count,
                what(prop)
            ),
        ),
        RecErr::Negative { prop, count } => ferr(
            path,
            format!("{} {i}{}: negative list count {count}", el.name, what(prop)),
        ),
        RecErr::TooBig {
            prop,
            count,
            bytes,
            left,
        } => ferr(
            path,
            format!(
                "unexpected end of file in {} {i} of {}{}: list count {count} needs {bytes} \
                 bytes, only {left} remain",
                el.name,
                el.count,
                what(prop)
            ),
        ),
    }
}

/// Parses one ascii line of `el`: scalars into `values`, items of list `list` into `items`.
/// Errors are messages without the file name.
pub(super) fn parse_ascii_record(
    line: &str,
    el: &Element,
    values: &mut [f64],
    list: Option<usize>,
    items: &mut Vec<i64>,
) -> Result<(), String> {
    let mut toks = line.split_ascii_whitespace();
    let mut seen = 0usize;
    let mut next = |what: &str| -> Result<&str, String> {
        seen += 1;
        toks.next()
            .ok_or_else(|| format!("too few values (property '{what}' is missing)"))
    };
    for (k, p) in el.props.iter().enumerate() {
        match p.ty {
            PropType::Scalar(s) => {
                let t = next(&p.name)?;
                let v = t.parse::<f64>().map_err(|_| {
                    format!("property '{}': '{}' is not a number", p.name, excerpt(t))
                })?;
                if let Some((lo, hi)) = s.int_range() {
                    let why = if !v.is_finite() || v.fract() != 0.0 {
                        Some("is not an integer".to_owned())
                    } else if v < lo as f64 || v > hi as f64 {
                        Some(format!("is outside its range {lo}..={hi}"))
                    } else {
                        None
                    };
                    if let Some(why) = why {
                        return Err(format!(
                            "property '{}' ({}): '{}' {why}",
                            p.name,
                            s.name(),
                            excerpt(t)
                        ));
                    }
                }
                values[k] = v;
            }
            PropType::List { .. } => {
                let t = next(&p.name)?;
                let n = parse_int(t).filter(|n| *n >= 0).ok_or_else(|| {
                    format!(
                        "property '{}': list count '{}' is not a non-negative integer",
                        p.name,
                        excerpt(t)
                    )
                })?;
                if Some(k) == list {
                    items.clear();
                }
                for _ in 0..n {
                    let t = next(&p.name)?;
                    if Some(k) == list {
                        let v = parse_int(t).ok_or_else(|| {
                            format!("property '{}': '{}' is not an integer", p.name, excerpt(t))
                        })?;
                        items.push(v);
                    }
                }
                values[k] = f64::NAN;
            }
        }
    }
    let extra = toks.count();
    if extra > 0 {
        return Err(format!(
            "too many values: {} found, the header declares {seen}",
            seen + extra
        ));
    }
    Ok(())
}

/// An integer token (`12`, also `12.0` as some writers emit).
fn parse_int(t: &str) -> Option<i64> {
    if let Ok(v) = t.parse::<i64>() {
        return Some(v);
    }
    let f = t.parse::<f64>().ok()?;
    (f.fract() == 0.0 && f.abs() < 9.0e15).then_some(f as i64)
}

/// The next non-blank ascii body line, with its number.
pub(super) fn next_ascii_line<'a>(
    input: &'a mut Input,
    line_no: &mut u64,
    path: &Path,
) -> Result<Option<(u64, &'a str)>, SceneError> {
    loop {
        *line_no += 1;
        let n = *line_no;
        let range = match input
            .next_line_range(usize::MAX)
            .map_err(|e| SceneError::io(path, e))?
        {
            LineRead::Line(r) => r,
            LineRead::Eof | LineRead::TooLong => return Ok(None),
        };
        let Ok(text) = std::str::from_utf8(&input.buf[range.clone()]) else {
            return Err(ferr(path, format!("line {n}: not ASCII text")));
        };
        if !text.trim().is_empty() {
            // Re-slice outside the loop's conditional borrow.
            let text = std::str::from_utf8(&input.buf[range]).unwrap_or_default();
            return Ok(Some((n, text)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn color_conversion() {
        assert_eq!(color_u8(200.0, Scalar::U8), 200);
        assert_eq!(color_u8(1.0, Scalar::F32), 255);
        assert_eq!(color_u8(0.5, Scalar::F64), 128);
        assert_eq!(color_u8(65535.0, Scalar::U16), 255);
        assert_eq!(color_u8(-3.0, Scalar::I32), 0);
        assert_eq!(color_u8(f64::NAN, Scalar::F32), 0);
    }
}
