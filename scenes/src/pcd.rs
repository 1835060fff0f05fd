//! PCD reader (the Point Cloud Library's format, header versions 0.6 and 0.7).
//!
//! # What is read
//! - The header: `VERSION` (optional), `FIELDS`, `SIZE`, `TYPE`, `COUNT` (optional, 1 per
//!   field by default), `WIDTH`, `HEIGHT`, `VIEWPOINT` (optional, parsed and checked, not
//!   applied: PCL keeps it as the sensor pose beside the points and does not transform them
//!   either), `POINTS` (must equal `WIDTH × HEIGHT`), `DATA ascii|binary|binary_compressed`.
//!   Lines starting with `#` are comments. Every other keyword is an error naming the line.
//! - The payload: `ascii` (one point per line, whitespace-separated, `nan` allowed),
//!   `binary` (packed little-endian records, fields in header order), `binary_compressed`
//!   (`u32` compressed size, `u32` uncompressed size, then an LZF stream of the fields laid
//!   out one after the other — all points' first field, then all points' second field, …).
//! - Fields used: `x y z` (required, `F` of size 4 or 8, or integers), `rgb` / `rgba` (PCL's
//!   packed colour: the 32 bits of the value, float or unsigned, are `0xAARRGGBB`),
//!   `normal_x normal_y normal_z`, and `intensity` ([`Pcd::intensity`], for `--shading
//!   intensity`). Other fields (`curvature`, padding `_`, …) are skipped; each is still
//!   checked for a valid `SIZE`/`TYPE`/`COUNT`.
//! - Organised clouds (`HEIGHT > 1`, e.g. a depth camera's grid) mark missing measurements
//!   with NaN coordinates: a point with any non-finite coordinate is dropped and counted in
//!   [`Pcd::dropped`]. When every point is dropped the file is an error.
//! - Normals: PCL writes NaN normals where it could not estimate one. If a kept point's normal
//!   is zero or not finite, the whole normal column is dropped and a warning says how many
//!   were invalid (a cloud has a normal for every sample or none).
//!
//! Positions are stored as `f32` relative to the centre of the kept points' bounds (in `f64`),
//! like the other readers. Errors name the file and the header line or field; a truncated
//! payload names the point it stops at.

use std::path::Path;

use crate::{PointCloud, SceneError};

/// A PCD file read into a cloud.
#[derive(Debug)]
pub struct Pcd {
    /// The points that had finite coordinates.
    pub cloud: PointCloud,
    /// Points dropped for a non-finite coordinate (the holes of an organised cloud).
    pub dropped: usize,
    /// The `intensity` field of the kept points, when the file has one.
    pub intensity: Option<Vec<f32>>,
    /// What was dropped or ignored, one sentence each, naming the file and the field.
    pub warnings: Vec<String>,
}

/// The storage of one field value.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    I,
    U,
    F,
}

#[derive(Debug, Clone)]
struct Field {
    name: String,
    kind: Kind,
    size: usize,
    count: usize,
    /// Byte offset inside a packed record.
    offset: usize,
}

impl Field {
    fn bytes(&self) -> usize {
        self.size * self.count
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Data {
    Ascii,
    Binary,
    Compressed,
}

#[derive(Debug)]
struct Header {
    fields: Vec<Field>,
    points: usize,
    data: Data,
    /// Byte offset of the payload.
    body: usize,
}

fn ferr(path: &Path, msg: impl Into<String>) -> SceneError {
    SceneError::format(path, msg)
}

/// Reads a PCD file.
pub fn read(path: &Path) -> Result<Pcd, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    let header = parse_header(path, &bytes)?;
    let body = &bytes[header.body..];
    let record: usize = header.fields.iter().map(Field::bytes).sum();
    let sel = Selection::new(path, &header.fields)?;
    let mut out = Columns::with_capacity(
        header
            .points
            .min(body.len() / record.max(1) + 1)
            .min(1 << 24),
        &sel,
    );
    match header.data {
        Data::Ascii => read_ascii(path, body, &header, &sel, &mut out)?,
        Data::Binary => {
            let need = header.points.saturating_mul(record);
            if body.len() < need {
                return Err(truncated(path, body.len() / record.max(1), header.points));
            }
            for rec in body[..need].chunks_exact(record) {
                out.push(&sel, |f| value(rec, f));
            }
        }
        Data::Compressed => {
            let raw = decompress_body(path, body, header.points, record)?;
            // Column-major: field f of point i is at points × offset(f) + i × bytes(f).
            let n = header.points;
            for i in 0..n {
                out.push(&sel, |f| {
                    let at = n * f.offset + i * f.bytes();
                    decode(&raw[at..at + f.size], f)
                });
            }
        }
    }
    out.finish(path, header.points)
}

fn truncated(path: &Path, have: usize, want: usize) -> SceneError {
    ferr(
        path,
        format!("the data stops at point {have} of the {want} the header declares (truncated)"),
    )
}

/// Parses the header; the error names the line.
fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, SceneError> {
    let mut h = HeaderLines::default();
    let mut pos = 0;
    let mut line_no = 0;
    while pos < bytes.len() {
        let end = bytes[pos..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |e| pos + e + 1);
        line_no += 1;
        let line = std::str::from_utf8(&bytes[pos..end])
            .map_err(|_| ferr(path, format!("header line {line_no} is not text")))?
            .trim();
        pos = end;
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or_default().to_ascii_uppercase();
        let rest: Vec<&str> = words.collect();
        let herr = |msg: String| ferr(path, format!("header line {line_no} ({key}): {msg}"));
        let uint = |w: &str| {
            w.parse::<usize>()
                .map_err(|_| herr(format!("'{w}' is not a non-negative integer")))
        };
        match key.as_str() {
            "VERSION" => {}
            "FIELDS" | "COLUMNS" => h.names = Some(rest.iter().map(|s| s.to_string()).collect()),
            "SIZE" => h.sizes = Some(rest.iter().map(|w| uint(w)).collect::<Result<_, _>>()?),
            "TYPE" => {
                h.types = Some(
                    rest.iter()
                        .map(|w| match *w {
                            "I" | "i" => Ok(Kind::I),
                            "U" | "u" => Ok(Kind::U),
                            "F" | "f" => Ok(Kind::F),
                            other => Err(herr(format!("type '{other}' is not I, U or F"))),
                        })
                        .collect::<Result<_, _>>()?,
                )
            }
            "COUNT" => h.counts = Some(rest.iter().map(|w| uint(w)).collect::<Result<_, _>>()?),
            "WIDTH" | "HEIGHT" | "POINTS" => {
                let [w] = rest[..] else {
                    return Err(herr("expected one integer".into()));
                };
                let v = uint(w)?;
                match key.as_str() {
                    "WIDTH" => h.width = Some(v),
                    "HEIGHT" => h.height = Some(v),
                    _ => h.points = Some(v),
                }
            }
            "VIEWPOINT" => {
                let ok = rest.len() == 7
                    && rest
                        .iter()
                        .all(|w| w.parse::<f64>().is_ok_and(f64::is_finite));
                if !ok {
                    return Err(herr("expected 7 numbers (tx ty tz qw qx qy qz)".into()));
                }
            }
            "DATA" => {
                let data = match rest.first().map(|s| s.to_ascii_lowercase()).as_deref() {
                    Some("ascii") => Data::Ascii,
                    Some("binary") => Data::Binary,
                    Some("binary_compressed") => Data::Compressed,
                    other => {
                        return Err(herr(format!(
                            "'{}' is not ascii, binary or binary_compressed",
                            other.unwrap_or("")
                        )));
                    }
                };
                return h.finish(path, data, pos);
            }
            other => return Err(herr(format!("unknown keyword '{other}'"))),
        }
    }
    Err(ferr(
        path,
        "the header has no DATA line (not a PCD file, or truncated)",
    ))
}

/// The header lines read before the DATA line, each `None` until its line is read.
#[derive(Default)]
struct HeaderLines {
    names: Option<Vec<String>>,
    sizes: Option<Vec<usize>>,
    types: Option<Vec<Kind>>,
    counts: Option<Vec<usize>>,
    width: Option<usize>,
    height: Option<usize>,
    points: Option<usize>,
}

impl HeaderLines {
    /// The header once the DATA line (`data`, the payload at byte `body`) is read: the
    /// fields (see [`fields`]), and a point count that is WIDTH × HEIGHT and not 0.
    fn finish(self, path: &Path, data: Data, body: usize) -> Result<Header, SceneError> {
        let names = self
            .names
            .ok_or_else(|| ferr(path, "the header has no FIELDS line"))?;
        let sizes = self
            .sizes
            .ok_or_else(|| ferr(path, "the header has no SIZE line"))?;
        let types = self
            .types
            .ok_or_else(|| ferr(path, "the header has no TYPE line"))?;
        let counts = self.counts.unwrap_or_else(|| vec![1; names.len()]);
        let fields = fields(path, names, sizes, types, counts)?;
        let width = self
            .width
            .ok_or_else(|| ferr(path, "the header has no WIDTH line"))?;
        let height = self.height.unwrap_or(1);
        let grid = width.checked_mul(height);
        let points = self.points.or(grid).unwrap_or(0);
        if grid != Some(points) {
            return Err(ferr(
                path,
                format!("POINTS {points} is not WIDTH {width} × HEIGHT {height}"),
            ));
        }
        if points == 0 {
            return Err(ferr(path, "the file holds no points (POINTS 0)"));
        }
        Ok(Header {
            fields,
            points,
            data,
            body,
        })
    }
}

/// The fields of the FIELDS, SIZE, TYPE and COUNT lines, with their offsets in a packed
/// record: one entry per field in each line, each of a PCD type and of COUNT 1..=65536.
fn fields(
    path: &Path,
    names: Vec<String>,
    sizes: Vec<usize>,
    types: Vec<Kind>,
    counts: Vec<usize>,
) -> Result<Vec<Field>, SceneError> {
    for (what, len) in [
        ("SIZE", sizes.len()),
        ("TYPE", types.len()),
        ("COUNT", counts.len()),
    ] {
        if len != names.len() {
            return Err(ferr(
                path,
                format!(
                    "{what} has {len} entries but FIELDS names {} fields",
                    names.len()
                ),
            ));
        }
    }
    let mut fields = Vec::with_capacity(names.len());
    let mut offset = 0usize;
    for (((name, size), kind), count) in names.into_iter().zip(sizes).zip(types).zip(counts) {
        let valid = match kind {
            Kind::F => matches!(size, 4 | 8),
            Kind::I | Kind::U => matches!(size, 1 | 2 | 4 | 8),
        };
        if !valid {
            return Err(ferr(
                path,
                format!("field '{name}': TYPE {kind:?} with SIZE {size} is not a PCD type"),
            ));
        }
        if count == 0 || count > 1 << 16 {
            return Err(ferr(
                path,
                format!("field '{name}': COUNT {count} is not in 1..=65536"),
            ));
        }
        let f = Field {
            name,
            kind,
            size,
            count,
            offset,
        };
        offset += f.bytes();
        fields.push(f);
    }
    Ok(fields)
}

/// Which fields feed which column.
struct Selection {
    xyz: [Field; 3],
    rgb: Option<Field>,
    normal: Option<[Field; 3]>,
    intensity: Option<Field>,
}

impl Selection {
    fn new(path: &Path, fields: &[Field]) -> Result<Self, SceneError> {
        let find = |n: &str| fields.iter().find(|f| f.name == n).cloned();
        let scalar = |f: Field| -> Result<Field, SceneError> {
            if f.count != 1 {
                return Err(ferr(
                    path,
                    format!("field '{}': COUNT {} (expected 1)", f.name, f.count),
                ));
            }
            Ok(f)
        };
        let triple = |names: [&str; 3]| -> Result<Option<[Field; 3]>, SceneError> {
            match names.map(find) {
                [Some(a), Some(b), Some(c)] => Ok(Some([scalar(a)?, scalar(b)?, scalar(c)?])),
                [None, None, None] => Ok(None),
                _ => Err(ferr(
                    path,
                    format!(
                        "fields {}: some are missing (give all three or none)",
                        names.join(" ")
                    ),
                )),
            }
        };
        let xyz = triple(["x", "y", "z"])?
            .ok_or_else(|| ferr(path, "no 'x y z' fields: a point cloud needs positions"))?;
        let rgb = match find("rgb").or_else(|| find("rgba")) {
            Some(f) => {
                let f = scalar(f)?;
                if f.size != 4 {
                    return Err(ferr(
                        path,
                        format!(
                            "field '{}': SIZE {} (packed colour is 4 bytes)",
                            f.name, f.size
                        ),
                    ));
                }
                Some(f)
            }
            None => None,
        };
        let normal = triple(["normal_x", "normal_y", "normal_z"])?;
        let intensity = find("intensity").map(scalar).transpose()?;
        Ok(Self {
            xyz,
            rgb,
            normal,
            intensity,
        })
    }
}

/// A field's value: a number, or (for packed colour) its 32 bits.
#[derive(Clone, Copy)]
enum Val {
    Num(f64),
    Bits(u32),
}

impl Val {
    fn num(self) -> f64 {
        match self {
            Val::Num(v) => v,
            Val::Bits(b) => f64::from(b),
        }
    }
    fn bits(self) -> u32 {
        match self {
            Val::Bits(b) => b,
            // An ascii packed float: its bit pattern is the colour.
            Val::Num(v) => (v as f32).to_bits(),
        }
    }
}

/// The value of field `f` (its first component) in a packed little-endian record.
fn value(rec: &[u8], f: &Field) -> Val {
    decode(&rec[f.offset..f.offset + f.size], f)
}

/// Decodes the `f.size` little-endian bytes `b` of field `f`.
fn decode(b: &[u8], f: &Field) -> Val {
    let arr = |n: usize| {
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(&b[..n]);
        a
    };
    match (f.kind, f.size) {
        // Packed colour: the bits, whatever the declared type.
        _ if f.size == 4 && (f.name == "rgb" || f.name == "rgba") => {
            Val::Bits(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        }
        (Kind::F, 4) => Val::Num(f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))),
        (Kind::F, _) => Val::Num(f64::from_le_bytes(arr(8))),
        (Kind::U, n) => Val::Num(u64::from_le_bytes(arr(n)) as f64),
        (Kind::I, n) => {
            let shift = 64 - 8 * n as u32;
            Val::Num(((i64::from_le_bytes(arr(n)) << shift) >> shift) as f64)
        }
    }
}

struct Columns {
    pos: Vec<[f64; 3]>,
    rgb: Option<Vec<[u8; 3]>>,
    normals: Option<Vec<[f32; 3]>>,
    intensity: Option<Vec<f32>>,
    bad_normals: usize,
    dropped: usize,
}

impl Columns {
    fn with_capacity(cap: usize, sel: &Selection) -> Self {
        Self {
            pos: Vec::with_capacity(cap),
            rgb: sel.rgb.as_ref().map(|_| Vec::with_capacity(cap)),
            normals: sel.normal.as_ref().map(|_| Vec::with_capacity(cap)),
            intensity: sel.intensity.as_ref().map(|_| Vec::with_capacity(cap)),
            bad_normals: 0,
            dropped: 0,
        }
    }

    /// Appends one point read through `get(field)`; drops it when a coordinate is not finite.
    fn push(&mut self, sel: &Selection, mut get: impl FnMut(&Field) -> Val) {
        let p = sel.xyz.each_ref().map(|f| get(f).num());
        if !p.iter().all(|c| c.is_finite()) {
            self.dropped += 1;
            return;
        }
        self.pos.push(p);
        if let (Some(f), Some(col)) = (&sel.rgb, self.rgb.as_mut()) {
            let b = get(f).bits();
            col.push([(b >> 16) as u8, (b >> 8) as u8, b as u8]);
        }
        if let (Some(f), Some(col)) = (&sel.intensity, self.intensity.as_mut()) {
            col.push(get(f).num() as f32);
        }
        if let (Some(fs), Some(col)) = (&sel.normal, self.normals.as_mut()) {
            let n = fs.each_ref().map(|f| get(f).num());
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if len.is_finite() && len > 1e-6 {
                col.push(n.map(|c| (c / len) as f32));
            } else {
                self.bad_normals += 1;
                col.push([0.0, 0.0, 1.0]);
            }
        }
    }

    fn finish(self, path: &Path, declared: usize) -> Result<Pcd, SceneError> {
        if self.pos.is_empty() {
            return Err(ferr(
                path,
                format!("all {declared} points have a non-finite coordinate (nothing to draw)"),
            ));
        }
        let (origin, local) = crate::cloud::centred(&self.pos);
        let mut warnings = Vec::new();
        let normals = match self.normals {
            Some(_) if self.bad_normals > 0 => {
                warnings.push(format!(
                    "{}: normals dropped: {} of {} kept points have a zero or non-finite normal",
                    path.display(),
                    self.bad_normals,
                    self.pos.len()
                ));
                None
            }
            n => n,
        };
        let cloud = PointCloud::new(
            origin,
            local.into(),
            normals.map(Into::into),
            self.rgb.map(Into::into),
            None,
        )
        .map_err(|e| ferr(path, e.to_string()))?;
        Ok(Pcd {
            cloud,
            dropped: self.dropped,
            intensity: self.intensity,
            warnings,
        })
    }
}

/// Reads an ascii payload: one point per line, `COUNT` tokens per field.
fn read_ascii(
    path: &Path,
    body: &[u8],
    header: &Header,
    sel: &Selection,
    out: &mut Columns,
) -> Result<(), SceneError> {
    let text = std::str::from_utf8(body).map_err(|_| ferr(path, "the ascii data is not text"))?;
    let tokens_per_point: usize = header.fields.iter().map(|f| f.count).sum();
    // Token index of each field's first component.
    let mut first = Vec::with_capacity(header.fields.len());
    let mut t = 0;
    for f in &header.fields {
        first.push(t);
        t += f.count;
    }
    let index = |f: &Field| {
        header
            .fields
            .iter()
            .position(|g| g.name == f.name)
            .map_or(0, |i| first[i])
    };
    let mut values: Vec<f64> = Vec::with_capacity(tokens_per_point);
    let mut raw: Vec<&str> = Vec::with_capacity(tokens_per_point);
    let mut i = 0usize;
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        if i == header.points {
            return Err(ferr(
                path,
                format!(
                    "more data lines than the {} points the header declares",
                    header.points
                ),
            ));
        }
        values.clear();
        raw.clear();
        for w in line.split_whitespace() {
            raw.push(w);
            let v = match w.to_ascii_lowercase().as_str() {
                "nan" | "-nan" => f64::NAN,
                "inf" | "+inf" => f64::INFINITY,
                "-inf" => f64::NEG_INFINITY,
                _ => w
                    .parse::<f64>()
                    .map_err(|_| ferr(path, format!("point {i}: '{w}' is not a number")))?,
            };
            values.push(v);
        }
        if values.len() != tokens_per_point {
            return Err(ferr(
                path,
                format!(
                    "point {i}: {} values, the header's fields need {tokens_per_point}",
                    values.len()
                ),
            ));
        }
        out.push(sel, |f| {
            let k = index(f);
            if f.name == "rgb" || f.name == "rgba" {
                // PCL writes packed colour as a float (rgb) or an unsigned integer (rgba):
                // parsed in its own type so the bits are exact.
                match f.kind {
                    Kind::F => Val::Bits(raw[k].parse::<f32>().map_or(0, f32::to_bits)),
                    _ => Val::Bits(raw[k].parse::<u32>().unwrap_or(values[k] as u32)),
                }
            } else if f.kind == Kind::F && f.size == 4 {
                // A float field holds what its f32 holds, as in a binary file.
                Val::Num(f64::from(values[k] as f32))
            } else {
                Val::Num(values[k])
            }
        });
        i += 1;
    }
    if i < header.points {
        return Err(truncated(path, i, header.points));
    }
    Ok(())
}

/// Unpacks a `binary_compressed` payload and checks its size against the header.
fn decompress_body(
    path: &Path,
    body: &[u8],
    points: usize,
    record: usize,
) -> Result<Vec<u8>, SceneError> {
    if body.len() < 8 {
        return Err(ferr(
            path,
            "binary_compressed data has no size words (truncated)",
        ));
    }
    let compressed = u32::from_le_bytes([body[0], body[1], body[2], body[3]]) as usize;
    let size = u32::from_le_bytes([body[4], body[5], body[6], body[7]]) as usize;
    let want = points.saturating_mul(record);
    if size != want {
        return Err(ferr(
            path,
            format!(
                "binary_compressed: uncompressed size {size} B, but {points} points × {record} B = {want} B"
            ),
        ));
    }
    let data = body.get(8..8 + compressed).ok_or_else(|| {
        ferr(
            path,
            format!(
                "binary_compressed: {compressed} B of compressed data declared, {} B present (truncated)",
                body.len() - 8
            ),
        )
    })?;
    lzf_decompress(data, size).map_err(|m| ferr(path, format!("binary_compressed: {m}")))
}

/// Decodes an LZF stream (liblzf's format) of exactly `size` bytes.
///
/// A control byte `c < 32` is followed by `c + 1` literal bytes; otherwise `c >> 5` (extended
/// by the next byte when it is 7) plus 2 bytes are copied from `((c & 31) << 8) + next + 1`
/// bytes back (copies may overlap their own output).
pub fn lzf_decompress(input: &[u8], size: usize) -> Result<Vec<u8>, String> {
    // One 3-byte code yields at most 264 bytes: never reserve more than the input can make.
    let mut out: Vec<u8> = Vec::with_capacity(size.min(input.len().saturating_mul(88)));
    let mut i = 0;
    let byte = |i: usize| input.get(i).copied().ok_or("the stream ends inside a code");
    while i < input.len() {
        let c = usize::from(input[i]);
        i += 1;
        if c < 32 {
            let run = input
                .get(i..i + c + 1)
                .ok_or("a literal run passes the end of the stream")?;
            if out.len() + run.len() > size {
                return Err(format!("decodes to more than the declared {size} B"));
            }
            out.extend_from_slice(run);
            i += c + 1;
        } else {
            let mut len = c >> 5;
            if len == 7 {
                len += usize::from(byte(i)?);
                i += 1;
            }
            len += 2;
            let back = ((c & 31) << 8) + usize::from(byte(i)?) + 1;
            i += 1;
            if back > out.len() {
                return Err(format!(
                    "a back-reference reaches {back} B back from byte {}",
                    out.len()
                ));
            }
            if out.len() + len > size {
                return Err(format!("decodes to more than the declared {size} B"));
            }
            let start = out.len() - back;
            for k in 0..len {
                let b = out[start + k];
                out.push(b);
            }
        }
    }
    if out.len() != size {
        return Err(format!(
            "decodes to {} B, the header declares {size} B",
            out.len()
        ));
    }
    Ok(out)
}
