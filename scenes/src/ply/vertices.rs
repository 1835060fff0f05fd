//! Vertex decoding: the property selection, ascii, fixed-size and variable-size binary records.

use std::path::Path;

use super::ferr;
use super::header::{Element, Encoding, Header, PropType, Scalar};
use super::input::Input;
use super::records::{
    RecErr, color_u8, next_ascii_line, parse_ascii_record, read_binary_record, rec_err, scalar_f64,
};
use crate::SceneError;

// ---------------------------------------------------------------------------------------------
// Vertices
// ---------------------------------------------------------------------------------------------

/// Which vertex properties feed which column.
pub(super) struct VertexSel {
    xyz: [usize; 3],
    normal: Option<[usize; 3]>,
    color: Option<([usize; 3], [Scalar; 3])>,
    radius: Option<usize>,
}

pub(super) fn select_vertex(el: &Element, path: &Path) -> Result<VertexSel, SceneError> {
    let scalar = |name: &str| -> Result<Option<(usize, Scalar)>, SceneError> {
        match el.find(name) {
            None => Ok(None),
            Some(k) => match el.props[k].ty {
                PropType::Scalar(s) => Ok(Some((k, s))),
                PropType::List { .. } => Err(ferr(
                    path,
                    format!("vertex property '{name}' is a list; expected a number"),
                )),
            },
        }
    };
    let mut xyz = [0usize; 3];
    for (slot, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
        *slot = scalar(name)?
            .ok_or_else(|| {
                ferr(
                    path,
                    format!("element vertex has no property '{name}' (x, y and z are required)"),
                )
            })?
            .0;
    }
    let triple = |names: [&str; 3]| -> Result<Option<[(usize, Scalar); 3]>, SceneError> {
        let (a, b, c) = (scalar(names[0])?, scalar(names[1])?, scalar(names[2])?);
        Ok(match (a, b, c) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        })
    };
    let normal = triple(["nx", "ny", "nz"])?.map(|t| t.map(|(k, _)| k));
    let color = match triple(["red", "green", "blue"])? {
        Some(t) => Some(t),
        None => match triple(["diffuse_red", "diffuse_green", "diffuse_blue"])? {
            Some(t) => Some(t),
            None => triple(["r", "g", "b"])?,
        },
    }
    .map(|t| (t.map(|(k, _)| k), t.map(|(_, s)| s)));
    let radius = scalar("radius")?.map(|(k, _)| k);
    Ok(VertexSel {
        xyz,
        normal,
        color,
        radius,
    })
}

/// Decoded vertex columns (positions in world `f64`).
pub(super) struct Vertices {
    pub(super) pos: Vec<[f64; 3]>,
    pub(super) normals: Option<Vec<[f32; 3]>>,
    pub(super) colors: Option<Vec<[u8; 3]>>,
    pub(super) radii: Option<Vec<f32>>,
    /// Vertices whose normal is zero or not finite (a placeholder stands in their place).
    pub(super) bad_normals: u64,
    /// The first of them: index and normal.
    pub(super) first_bad: Option<(u64, [f64; 3])>,
}

impl Vertices {
    fn with_capacity(sel: &VertexSel, cap: usize) -> Vertices {
        Vertices {
            pos: Vec::with_capacity(cap),
            normals: sel.normal.map(|_| Vec::with_capacity(cap)),
            colors: sel.color.map(|_| Vec::with_capacity(cap)),
            radii: sel.radius.map(|_| Vec::with_capacity(cap)),
            bad_normals: 0,
            first_bad: None,
        }
    }
}

/// Property values of one record, by property index.
trait Record {
    fn get(&self, k: usize) -> f64;
}

/// A record already parsed into one value per property.
struct Parsed<'a>(&'a [f64]);

impl Record for Parsed<'_> {
    #[inline(always)]
    fn get(&self, k: usize) -> f64 {
        self.0.get(k).copied().unwrap_or(f64::NAN)
    }
}

/// A fixed-size binary record and the `(offset, type)` layout of its properties.
struct Fixed<'a, const BE: bool> {
    rec: &'a [u8],
    layout: &'a [(usize, Scalar)],
}

impl<const BE: bool> Record for Fixed<'_, BE> {
    #[inline(always)]
    fn get(&self, k: usize) -> f64 {
        match self.layout.get(k) {
            Some(&(off, ty)) => scalar_f64::<BE>(self.rec, off, ty),
            None => f64::NAN,
        }
    }
}

/// Appends one vertex, reading its properties from `rec`. A zero or non-finite normal is
/// counted (the column is dropped at the end) and a placeholder keeps the columns aligned.
#[inline(always)]
fn push_vertex(out: &mut Vertices, sel: &VertexSel, rec: &impl Record) {
    let get = |k: usize| rec.get(k);
    out.pos.push(sel.xyz.map(get));
    if let (Some(idx), Some(col)) = (sel.normal, out.normals.as_mut()) {
        let n = idx.map(get);
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if l.is_finite() && l > 1e-30 {
            col.push(n.map(|c| (c / l) as f32));
        } else {
            out.bad_normals += 1;
            if out.first_bad.is_none() {
                out.first_bad = Some((out.pos.len() as u64 - 1, n));
            }
            col.push([0.0, 0.0, 1.0]);
        }
    }
    if let (Some((idx, ty)), Some(col)) = (sel.color, out.colors.as_mut()) {
        col.push([
            color_u8(get(idx[0]), ty[0]),
            color_u8(get(idx[1]), ty[1]),
            color_u8(get(idx[2]), ty[2]),
        ]);
    }
    if let (Some(k), Some(col)) = (sel.radius, out.radii.as_mut()) {
        col.push(get(k) as f32);
    }
}

pub(super) fn read_vertices(
    input: &mut Input,
    header: &Header,
    el: &Element,
    sel: &VertexSel,
    line_no: &mut u64,
    path: &Path,
) -> Result<Vertices, SceneError> {
    let ascii = header.encoding == Encoding::Ascii;
    let cap = el
        .count
        .min(input.remaining() / el.min_record_bytes(ascii) + 1);
    let mut out = Vertices::with_capacity(sel, usize::try_from(cap).unwrap_or(0));
    match header.encoding {
        Encoding::Ascii => {
            let mut values = vec![0.0f64; el.props.len()];
            let mut items = Vec::new();
            for i in 0..el.count {
                let Some((n, line)) = next_ascii_line(input, line_no, path)? else {
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in vertex {i} of {}", el.count),
                    ));
                };
                parse_ascii_record(line, el, &mut values, None, &mut items)
                    .map_err(|m| ferr(path, format!("line {n} (vertex {i}): {m}")))?;
                push_vertex(&mut out, sel, &Parsed(&values));
            }
        }
        Encoding::Binary { big_endian } => match (el.fixed_size(), big_endian) {
            (Some(rs), false) => read_fixed::<false>(input, el, rs, sel, &mut out, path)?,
            (Some(rs), true) => read_fixed::<true>(input, el, rs, sel, &mut out, path)?,
            (None, false) => read_variable::<false>(input, el, sel, &mut out, path)?,
            (None, true) => read_variable::<true>(input, el, sel, &mut out, path)?,
        },
    }
    Ok(out)
}

/// The fast path: fixed-size binary records decoded from a precomputed layout.
fn read_fixed<const BE: bool>(
    input: &mut Input,
    el: &Element,
    rs: usize,
    sel: &VertexSel,
    out: &mut Vertices,
    path: &Path,
) -> Result<(), SceneError> {
    // (offset, type) of every property.
    let mut layout = Vec::with_capacity(el.props.len());
    let mut off = 0;
    for p in &el.props {
        if let PropType::Scalar(s) = p.ty {
            layout.push((off, s));
            off += s.size();
        }
    }
    let count = el.count;
    let mut i: u64 = 0;
    while i < count {
        if !input.fill(rs).map_err(|e| SceneError::io(path, e))? {
            let have = input.avail().len();
            let prop = layout
                .iter()
                .position(|(o, s)| o + s.size() > have)
                .unwrap_or(0);
            return Err(rec_err(path, el, i, RecErr::Eof { prop }));
        }
        let avail = input.avail();
        let k = ((avail.len() / rs) as u64).min(count - i) as usize;
        for rec in avail[..k * rs].chunks_exact(rs) {
            let rec = Fixed::<BE> {
                rec,
                layout: &layout,
            };
            push_vertex(out, sel, &rec);
        }
        input.consume(k * rs);
        i += k as u64;
    }
    Ok(())
}

/// Binary vertex records with list properties (rare): one property at a time.
fn read_variable<const BE: bool>(
    input: &mut Input,
    el: &Element,
    sel: &VertexSel,
    out: &mut Vertices,
    path: &Path,
) -> Result<(), SceneError> {
    let mut values = vec![0.0f64; el.props.len()];
    let mut items = Vec::new();
    for i in 0..el.count {
        read_binary_record::<BE>(input, el, &mut values, None, &mut items)
            .map_err(|e| rec_err(path, el, i, e))?;
        push_vertex(out, sel, &Parsed(&values));
    }
    Ok(())
}
