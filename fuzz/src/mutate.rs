//! Mutations: generic byte edits, and edits that know a format's header (PLY header lines,
//! LAS header fields, TOML values). Every mutation draws from the one [`Pcg32`] it is given,
//! so an input is a pure function of the seed file and the random stream.

use scenes::rng::Pcg32;

/// Values that tend to sit on a decoder's edges, as little-endian integers of any width.
const INTERESTING: [u64; 16] = [
    0,
    1,
    2,
    3,
    7,
    8,
    16,
    255,
    256,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    0x7fff_ffff_ffff_ffff,
    u64::MAX,
];

/// A random index below `n` (`n` ≥ 1).
pub fn below(r: &mut Pcg32, n: usize) -> usize {
    if n <= 1 {
        return 0;
    }
    if let Ok(n32) = u32::try_from(n) {
        r.below(n32) as usize
    } else {
        (((u64::from(r.next_u32()) << 32) | u64::from(r.next_u32())) % n as u64) as usize
    }
}

fn chance(r: &mut Pcg32, one_in: u32) -> bool {
    r.below(one_in) == 0
}

/// An interesting value, or one near `near` (a count or length the file already holds).
pub fn interesting(r: &mut Pcg32, near: u64) -> u64 {
    match r.below(4) {
        0 | 1 => INTERESTING[below(r, INTERESTING.len())],
        2 => near.wrapping_add(u64::from(r.below(5))).wrapping_sub(2),
        _ => near.wrapping_mul(u64::from(r.below(1000)) + 2),
    }
}

/// Overwrites `width` bytes at `at` (clipped to the buffer) with `v`, little-endian.
pub fn put_le(b: &mut [u8], at: usize, width: usize, v: u64) {
    for (k, byte) in v.to_le_bytes().iter().take(width).enumerate() {
        if let Some(slot) = b.get_mut(at.saturating_add(k)) {
            *slot = *byte;
        }
    }
}

/// Reads `width` ≤ 8 bytes at `at` as a little-endian integer (missing bytes read as 0).
pub fn get_le(b: &[u8], at: usize, width: usize) -> u64 {
    let mut w = [0u8; 8];
    for (k, slot) in w.iter_mut().take(width).enumerate() {
        *slot = b.get(at.saturating_add(k)).copied().unwrap_or(0);
    }
    u64::from_le_bytes(w)
}

/// One generic byte-level mutation: bit flips, random or interesting bytes and integers,
/// truncation, extension, insertion, deletion, duplication, or a splice from `other`.
pub fn bytes(r: &mut Pcg32, b: &mut Vec<u8>, other: &[u8]) {
    if b.is_empty() {
        b.extend((0..1 + r.below(16)).map(|_| r.next_u32() as u8));
        return;
    }
    let n = b.len();
    let at = below(r, n);
    match r.below(12) {
        0 => b[at] ^= 1 << r.below(8),
        1 => b[at] = r.next_u32() as u8,
        2 => b[at] = [0, 0xff, 0x7f, 0x80, b'\n', b' ', b'0', b'-'][below(r, 8)],
        3 => {
            let width = [1, 2, 4, 8][below(r, 4)];
            let near = get_le(b, at, width);
            put_le(b, at, width, interesting(r, near));
        }
        4 => b.truncate(at),
        5 => {
            let extra = 1 + below(r, 64);
            b.extend((0..extra).map(|_| r.next_u32() as u8));
        }
        6 => {
            let k = 1 + below(r, 16);
            let ins: Vec<u8> = (0..k).map(|_| r.next_u32() as u8).collect();
            b.splice(at..at, ins);
        }
        7 => {
            let end = (at + 1 + below(r, 64)).min(n);
            b.drain(at..end);
        }
        8 => {
            let end = (at + 1 + below(r, 256)).min(n);
            let piece = b[at..end].to_vec();
            let to = below(r, b.len() + 1);
            b.splice(to..to, piece);
        }
        9 if !other.is_empty() => {
            let from = below(r, other.len());
            let end = (from + 1 + below(r, 512)).min(other.len());
            let to = below(r, b.len());
            let stop = (to + (end - from)).min(b.len());
            b.splice(to..stop, other[from..end].iter().copied());
        }
        10 => {
            // A run of bit flips close together (a damaged sector).
            for _ in 0..1 + r.below(8) {
                let k = (at + below(r, 32)).min(n - 1);
                b[k] ^= 1 << r.below(8);
            }
        }
        _ => {
            // A random integer of 2, 4 or 8 bytes.
            let width = [2, 4, 8][below(r, 3)];
            let v = (u64::from(r.next_u32()) << 32) | u64::from(r.next_u32());
            put_le(b, at, width, v);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Text: PLY headers and bodies, TOML
// ---------------------------------------------------------------------------------------------

/// Byte offset of a PLY body (after `end_header\n`), if the header is intact.
pub fn ply_body(b: &[u8]) -> Option<usize> {
    b.windows(11)
        .position(|w| w == b"end_header\n")
        .map(|p| p + 11)
}

const PLY_TYPES: [&str; 12] = [
    "char",
    "uchar",
    "short",
    "ushort",
    "int",
    "uint",
    "float",
    "double",
    "int8",
    "float64",
    "list uchar int",
    "list int float",
];

/// A number written as text that tends to break parsers.
fn odd_number(r: &mut Pcg32, near: u64) -> String {
    match r.below(10) {
        0 => "-1".into(),
        1 => "0".into(),
        2 => u64::MAX.to_string(),
        3 => "18446744073709551616".into(),
        4 => "4294967296".into(),
        5 => "0.302".into(),
        6 => ["nan", "inf", "-inf", "1e308", "-0", "1e-320"][below(r, 6)].into(),
        7 => near.saturating_add(1).to_string(),
        8 => near.saturating_sub(1).to_string(),
        _ => interesting(r, near).to_string(),
    }
}

/// One PLY-aware mutation: an element count, a property type, the format line, a header
/// line removed or doubled, or (ascii bodies) a token or a line of the body.
pub fn ply(r: &mut Pcg32, b: &mut Vec<u8>) {
    let Some(body) = ply_body(b) else {
        return;
    };
    let header = String::from_utf8_lossy(&b[..body]).into_owned();
    let mut lines: Vec<String> = header.lines().map(str::to_owned).collect();
    let ascii = header.contains("format ascii");
    let pick = |r: &mut Pcg32, lines: &[String], prefix: &str| {
        let idx: Vec<usize> = (0..lines.len())
            .filter(|&i| lines[i].starts_with(prefix))
            .collect();
        (!idx.is_empty()).then(|| idx[below(r, idx.len())])
    };
    let body_edit = ascii && chance(r, 3);
    if !body_edit {
        match r.below(6) {
            0 | 1 => {
                if let Some(i) = pick(r, &lines, "element ") {
                    let parts: Vec<&str> = lines[i].split_whitespace().collect();
                    let count = parts.get(2).and_then(|c| c.parse().ok()).unwrap_or(0);
                    let name = parts.get(1).copied().unwrap_or("vertex");
                    lines[i] = format!("element {name} {}", odd_number(r, count));
                }
            }
            2 => {
                if let Some(i) = pick(r, &lines, "property ") {
                    let name = lines[i].split_whitespace().last().unwrap_or("x").to_owned();
                    lines[i] = format!("property {} {name}", PLY_TYPES[below(r, PLY_TYPES.len())]);
                }
            }
            3 => {
                if let Some(i) = pick(r, &lines, "format ") {
                    lines[i] = [
                        "format ascii 1.0",
                        "format binary_little_endian 1.0",
                        "format binary_big_endian 1.0",
                    ][below(r, 3)]
                    .into();
                }
            }
            4 => {
                if lines.len() > 3 {
                    let i = 1 + below(r, lines.len() - 2);
                    lines.remove(i);
                }
            }
            _ => {
                if lines.len() > 2 {
                    let i = 1 + below(r, lines.len() - 2);
                    let l = lines[i].clone();
                    lines.insert(i, l);
                }
            }
        }
        let mut out = lines.join("\n").into_bytes();
        out.push(b'\n');
        out.extend_from_slice(&b[body..]);
        *b = out;
        return;
    }
    // Ascii body: change one token, or drop / double one line.
    let text = String::from_utf8_lossy(&b[body..]).into_owned();
    let mut rows: Vec<String> = text.lines().map(str::to_owned).collect();
    if rows.is_empty() {
        return;
    }
    let i = below(r, rows.len());
    match r.below(4) {
        0 => {
            rows.remove(i);
        }
        1 => {
            let l = rows[i].clone();
            rows.insert(i, l);
        }
        _ => {
            let mut toks: Vec<String> = rows[i].split_whitespace().map(str::to_owned).collect();
            if !toks.is_empty() {
                let k = below(r, toks.len());
                let near = toks[k].parse::<f64>().map_or(0, |v| v.abs() as u64);
                toks[k] = odd_number(r, near);
                if chance(r, 4) {
                    toks.push(odd_number(r, 1));
                }
                rows[i] = toks.join(" ");
            }
        }
    }
    let mut out = b[..body].to_vec();
    out.extend_from_slice(rows.join("\n").as_bytes());
    out.push(b'\n');
    *b = out;
}

/// One TOML- or JSON-aware mutation (JSON as the methods write it, one key per line): a
/// value replaced by one of another type or an extreme, a line removed or doubled, a key
/// renamed, or a stray table or key added.
pub fn toml(r: &mut Pcg32, b: &mut Vec<u8>) {
    let text = String::from_utf8_lossy(b).into_owned();
    let mut lines: Vec<String> = text.lines().map(str::to_owned).collect();
    if lines.is_empty() {
        lines.push(String::new());
    }
    let i = below(r, lines.len());
    const VALUES: [&str; 20] = [
        "0",
        "-1",
        "1e308",
        "nan",
        "inf",
        "-inf",
        "18446744073709551615",
        "9223372036854775807",
        "\"\"",
        "\"statue:0\"",
        "\"x.ply\"",
        "\"../../etc\"",
        "true",
        "[]",
        "[1, 2]",
        "[0.0, 0.0, 0.0]",
        "[nan, 0, 0]",
        "{}",
        "1979-05-27",
        "\"y\"",
    ];
    // TOML `key = value`, or a pretty-printed JSON `"key": value,` line.
    let json = text.trim_start().starts_with('{');
    let sep = if json { ':' } else { '=' };
    match r.below(6) {
        0 | 1 => {
            if let Some((k, v)) = lines[i].split_once(sep) {
                let comma = if json && v.trim_end().ends_with(',') {
                    ","
                } else {
                    ""
                };
                lines[i] = format!("{k}{sep} {}{comma}", VALUES[below(r, VALUES.len())]);
            }
        }
        2 => {
            lines.remove(i);
        }
        3 => {
            let l = lines[i].clone();
            lines.insert(i, l);
        }
        4 => {
            if let Some((k, v)) = lines[i].split_once(sep) {
                let k = k.trim();
                let mut renamed: String = k.to_owned();
                renamed.pop();
                renamed.push((b'a' + r.below(26) as u8) as char);
                lines[i] = format!("{renamed} {sep}{v}");
            }
        }
        _ => {
            let extra = ["[[key]]", "[key]", "t = 0.5", "up = \"q\"", "fov_deg = 0"];
            lines.insert(i, extra[below(r, extra.len())].into());
        }
    }
    *b = lines.join("\n").into_bytes();
    b.push(b'\n');
}

// ---------------------------------------------------------------------------------------------
// LAS / LAZ header fields
// ---------------------------------------------------------------------------------------------

/// `(offset, width)` of the LAS header fields a reader sizes or seeks by.
const LAS_FIELDS: [(usize, usize); 16] = [
    (94, 2),  // header size
    (96, 4),  // offset to point data
    (100, 4), // number of VLRs
    (104, 1), // point data format (bit 7: compressed)
    (105, 2), // point data record length
    (107, 4), // legacy point count
    (131, 8), // x scale factor
    (147, 8), // z scale factor
    (155, 8), // x offset
    (179, 8), // max x
    (227, 8), // 1.3+: start of waveform data
    (235, 8), // 1.4: start of first EVLR
    (243, 4), // 1.4: number of EVLRs
    (247, 8), // 1.4: point count
    (24, 1),  // version major
    (25, 1),  // version minor
];

/// One LAS/LAZ-aware mutation: a header field, a VLR header's length, the LAZ chunk-table
/// offset or the chunk table's count, or a laszip VLR field.
pub fn las(r: &mut Pcg32, b: &mut [u8]) {
    if b.len() < 227 {
        return;
    }
    let points_at = get_le(b, 96, 4) as usize;
    match r.below(8) {
        0..=3 => {
            let (at, width) = LAS_FIELDS[below(r, LAS_FIELDS.len())];
            if width == 8 && (131..179).contains(&at) && chance(r, 2) {
                let v = [0.0, -0.0, f64::NAN, f64::INFINITY, 1e-300, 1e300][below(r, 6)];
                put_le(b, at, 8, f64::to_bits(v));
            } else if at == 104 {
                b[at] = [0, 1, 2, 3, 6, 7, 10, 11, 0x80, 0x83, 0x86, 0x8a, 0xc3][below(r, 13)];
            } else if at == 25 {
                b[at] = r.below(6) as u8;
            } else {
                let near = get_le(b, at, width);
                put_le(b, at, width, interesting(r, near));
            }
        }
        4 => {
            // The LAZ chunk-table offset (first 8 bytes of the point data) or the table.
            let table = get_le(b, points_at, 8) as usize;
            if chance(r, 2) && table.checked_add(8).is_some_and(|e| e <= b.len()) {
                let near = get_le(b, table + 4, 4);
                put_le(b, table + 4, 4, interesting(r, near));
            } else {
                let v = if chance(r, 2) {
                    below(r, b.len() + 16) as u64
                } else {
                    interesting(r, table as u64)
                };
                put_le(b, points_at, 8, v);
            }
        }
        5 => {
            // Inside the first chunk: layer sizes of layered LAZ, counts, raw first point.
            let at = points_at + 8 + below(r, 96);
            let near = get_le(b, at, 4);
            put_le(b, at, 4, interesting(r, near));
        }
        _ => {
            // A VLR header's record length, or a field of the laszip VLR.
            let mut pos = get_le(b, 94, 2) as usize;
            let count = get_le(b, 100, 4).min(16) as usize;
            let target = below(r, count.max(1));
            for k in 0..count {
                if pos + 54 > b.len() {
                    return;
                }
                let len = get_le(b, pos + 20, 2) as usize;
                if k == target {
                    if &b[pos + 2..pos + 16] == b"laszip encoded" && chance(r, 2) {
                        let data = pos + 54;
                        let (off, width) =
                            [(0, 2), (12, 4), (32, 2), (34, 2), (36, 2), (38, 2)][below(r, 6)];
                        let near = get_le(b, data + off, width);
                        put_le(b, data + off, width, interesting(r, near));
                    } else {
                        put_le(b, pos + 20, 2, interesting(r, len as u64));
                    }
                    return;
                }
                pos += 54 + len;
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// PCD headers, E57 pages
// ---------------------------------------------------------------------------------------------

/// One PCD-aware mutation: a number of a header line (`POINTS`, `WIDTH`, `SIZE`, `COUNT`, …),
/// a `TYPE` letter, the `DATA` encoding, or (compressed bodies) the two sizes before the data.
pub fn pcd(r: &mut Pcg32, b: &mut Vec<u8>) {
    let Some(data) = b.windows(5).position(|w| w == b"DATA ") else {
        return;
    };
    let Some(end) = b[data..]
        .iter()
        .position(|&c| c == b'\n')
        .map(|k| data + k + 1)
    else {
        return;
    };
    if b[data..end].starts_with(b"DATA binary_compressed") && r.below(3) == 0 {
        let at = end + 4 * below(r, 2);
        let near = get_le(b, at, 4);
        put_le(b, at, 4, interesting(r, near));
        return;
    }
    let header = String::from_utf8_lossy(&b[..end]).into_owned();
    let mut lines: Vec<String> = header.lines().map(str::to_owned).collect();
    let i = below(r, lines.len());
    let mut toks: Vec<String> = lines[i].split_whitespace().map(str::to_owned).collect();
    if toks.len() >= 2 {
        let k = 1 + below(r, toks.len() - 1);
        toks[k] = match toks[0].as_str() {
            "TYPE" => ["F", "U", "I", "X"][below(r, 4)].into(),
            "DATA" => {
                ["ascii", "binary", "binary_compressed", "binary_compressed"][below(r, 4)].into()
            }
            "FIELDS" => ["x", "y", "z", "rgb", "normal_x", "_"][below(r, 6)].into(),
            _ => {
                let near = toks[k].parse::<f64>().map_or(0, |v| v.abs() as u64);
                odd_number(r, near)
            }
        };
        lines[i] = toks.join(" ");
    }
    let mut out = lines.join("\n").into_bytes();
    out.push(b'\n');
    out.extend_from_slice(&b[end..]);
    *b = out;
}

/// CRC-32C (Castagnoli), as E57 pages carry it.
fn crc32c(data: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &byte in data {
        crc ^= u32::from(byte);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0x82F6_3B78
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Recomputes the big-endian CRC-32C at the end of every page of an E57 file (page size from
/// its header, 1024 when that is not sane), so mutations reach the parser behind the check.
pub fn reseal_e57(b: &mut [u8]) {
    let page = get_le(b, 40, 8);
    let page = if (8..=1 << 20).contains(&page) {
        page as usize
    } else {
        1024
    };
    for p in b.chunks_exact_mut(page) {
        let sum = crc32c(&p[..page - 4]);
        p[page - 4..].copy_from_slice(&sum.to_be_bytes());
    }
}
