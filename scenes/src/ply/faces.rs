//! Face lists (fan-triangulated) and skipping the elements nobody needs.

use std::path::Path;

use super::ferr;
use super::header::{Element, Encoding, Header, PropType};
use super::input::Input;
use super::records::{next_ascii_line, parse_ascii_record, read_binary_record, rec_err};
use crate::SceneError;

// ---------------------------------------------------------------------------------------------
// Faces and other elements
// ---------------------------------------------------------------------------------------------

/// Index of the face element's vertex index list.
pub(super) fn face_list(el: &Element, path: &Path) -> Result<usize, SceneError> {
    let k = el
        .find("vertex_indices")
        .or_else(|| el.find("vertex_index"))
        .ok_or_else(|| {
            ferr(
                path,
                "element face has no list property 'vertex_indices' (or 'vertex_index')",
            )
        })?;
    match el.props[k].ty {
        PropType::List { item, .. } if item.is_integer() => Ok(k),
        PropType::List { .. } => Err(ferr(
            path,
            format!(
                "face property '{}' holds floating-point values; vertex indices must be integers",
                el.props[k].name
            ),
        )),
        PropType::Scalar(_) => Err(ferr(
            path,
            format!("face property '{}' is not a list", el.props[k].name),
        )),
    }
}

/// Fan-triangulates one face, checking its indices.
fn push_face(
    tris: &mut Vec<[u32; 3]>,
    items: &[i64],
    nverts: u64,
    face: u64,
) -> Result<(), String> {
    if let Some(bad) = items.iter().find(|&&v| v < 0 || v as u64 >= nverts) {
        return Err(format!(
            "face {face}: vertex index {bad} is out of range (the file has {nverts} vertices)"
        ));
    }
    if items.len() < 3 {
        return Ok(());
    }
    let v0 = items[0] as u32;
    for w in items[1..].windows(2) {
        tris.push([v0, w[0] as u32, w[1] as u32]);
    }
    Ok(())
}

pub(super) fn read_faces(
    input: &mut Input,
    header: &Header,
    el: &Element,
    list: usize,
    nverts: u64,
    line_no: &mut u64,
    path: &Path,
) -> Result<Vec<[u32; 3]>, SceneError> {
    let ascii = header.encoding == Encoding::Ascii;
    let cap = el
        .count
        .min(input.remaining() / el.min_record_bytes(ascii) + 1);
    let mut tris = Vec::with_capacity(usize::try_from(cap).unwrap_or(0));
    let mut values = vec![0.0f64; el.props.len()];
    let mut items = Vec::new();
    for i in 0..el.count {
        match header.encoding {
            Encoding::Ascii => {
                let Some((n, line)) = next_ascii_line(input, line_no, path)? else {
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in face {i} of {}", el.count),
                    ));
                };
                parse_ascii_record(line, el, &mut values, Some(list), &mut items)
                    .map_err(|m| ferr(path, format!("line {n} (face {i}): {m}")))?;
                push_face(&mut tris, &items, nverts, i)
                    .map_err(|m| ferr(path, format!("line {n}: {m}")))?;
            }
            Encoding::Binary { big_endian } => {
                let r = if big_endian {
                    read_binary_record::<true>(input, el, &mut values, Some(list), &mut items)
                } else {
                    read_binary_record::<false>(input, el, &mut values, Some(list), &mut items)
                };
                r.map_err(|e| rec_err(path, el, i, e))?;
                push_face(&mut tris, &items, nverts, i).map_err(|m| ferr(path, m))?;
            }
        }
    }
    Ok(tris)
}

/// Skips every record of an element nobody needs.
pub(super) fn skip_element(
    input: &mut Input,
    header: &Header,
    el: &Element,
    line_no: &mut u64,
    path: &Path,
) -> Result<(), SceneError> {
    match header.encoding {
        Encoding::Ascii => {
            for i in 0..el.count {
                if next_ascii_line(input, line_no, path)?.is_none() {
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in {} {i} of {}", el.name, el.count),
                    ));
                }
            }
        }
        Encoding::Binary { big_endian } => {
            if let Some(rs) = el.fixed_size() {
                let total = el.count.saturating_mul(rs as u64);
                if !input.skip(total).map_err(|e| SceneError::io(path, e))? {
                    let i = input.remaining() / (rs.max(1) as u64);
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in {} {i} of {}", el.name, el.count),
                    ));
                }
            } else {
                let mut values = vec![0.0f64; el.props.len()];
                let mut items = Vec::new();
                for i in 0..el.count {
                    let r = if big_endian {
                        read_binary_record::<true>(input, el, &mut values, None, &mut items)
                    } else {
                        read_binary_record::<false>(input, el, &mut values, None, &mut items)
                    };
                    r.map_err(|e| rec_err(path, el, i, e))?;
                }
            }
        }
    }
    Ok(())
}
