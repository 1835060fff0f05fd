//! The preamble both chunk codecs of the store start with, LPC's clouds
//! ([`crate::lpc::cloud`]) and MWKD's nodes ([`crate::mwkd::codec`]). Little-endian:
//!
//! | bytes | field                                                       |
//! |-------|-------------------------------------------------------------|
//! | 2     | magic (the codec's)                                         |
//! | 1     | version (the codec's)                                       |
//! | 1     | flags: bit 0 normals, bit 1 colours (other bits must be 0)  |
//! | 4     | `count` (u32)                                               |
//!
//! The codec's own fields follow, up to its fixed header length ([`Format::header_bytes`]).
//! Errors are messages without the chunk's name: each codec adds its own (`cloud {id}`,
//! `node {id}`) and its file.

/// Bytes of the preamble.
pub const PREAMBLE_BYTES: usize = 8;
/// Flag bit: normals are stored.
pub const FLAG_NORMALS: u8 = 1;
/// Flag bit: colours are stored.
pub const FLAG_COLORS: u8 = 2;

/// A chunk codec: what its preamble must say and how long its fixed header is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Format {
    /// First two bytes.
    pub magic: [u8; 2],
    /// Third byte.
    pub version: u8,
    /// Bytes of the codec's fixed header, preamble included (at least [`PREAMBLE_BYTES`]).
    pub header_bytes: usize,
}

/// What a preamble says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Preamble {
    /// Samples (points) in the chunk.
    pub count: u32,
    /// Normals are stored.
    pub normals: bool,
    /// Colours are stored.
    pub colors: bool,
}

impl Preamble {
    /// The flags byte.
    pub fn flags(&self) -> u8 {
        (u8::from(self.normals) * FLAG_NORMALS) | (u8::from(self.colors) * FLAG_COLORS)
    }
}

impl Format {
    /// Appends the preamble `p` in this format.
    pub fn write(&self, p: &Preamble, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.magic);
        out.push(self.version);
        out.push(p.flags());
        out.extend_from_slice(&p.count.to_le_bytes());
    }

    /// Reads the preamble of `bytes` after checking that they hold at least the fixed
    /// header, then the magic and version, then that no unknown flag bit is set.
    pub fn parse(&self, bytes: &[u8]) -> Result<Preamble, String> {
        let header = self.header_bytes.max(PREAMBLE_BYTES);
        if bytes.len() < header {
            return Err(format!(
                "{} bytes, shorter than the {header}-byte header",
                bytes.len()
            ));
        }
        if bytes[..2] != self.magic || bytes[2] != self.version {
            return Err("bad magic or version".into());
        }
        let flags = bytes[3];
        if flags & !(FLAG_NORMALS | FLAG_COLORS) != 0 {
            return Err(format!("unknown flags {flags:#x}"));
        }
        Ok(Preamble {
            count: le_u32(bytes, 4),
            normals: flags & FLAG_NORMALS != 0,
            colors: flags & FLAG_COLORS != 0,
        })
    }
}

/// The little-endian u32 at byte `at` of `bytes` (which must hold `at + 4` bytes: callers
/// read inside a header whose length they checked).
#[inline]
pub fn le_u32(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
}

#[cfg(test)]
mod tests {
    use super::*;

    const F: Format = Format {
        magic: *b"ZZ",
        version: 3,
        header_bytes: 12,
    };

    /// `p` written in `F`, padded to its header length.
    fn header(p: &Preamble) -> Vec<u8> {
        let mut out = Vec::new();
        F.write(p, &mut out);
        assert_eq!(out.len(), PREAMBLE_BYTES);
        out.resize(F.header_bytes, 0);
        out
    }

    #[test]
    fn round_trip() {
        for (count, normals, colors) in [
            (1, false, false),
            (7, true, false),
            (0x0102_0304, false, true),
            (u32::MAX, true, true),
        ] {
            let p = Preamble {
                count,
                normals,
                colors,
            };
            let bytes = header(&p);
            assert_eq!(&bytes[..4], &[b'Z', b'Z', 3, p.flags()]);
            assert_eq!(&bytes[4..8], &count.to_le_bytes());
            assert_eq!(F.parse(&bytes), Ok(p));
        }
        // Trailing bytes (the codec's body) are not the preamble's business.
        let p = Preamble {
            count: 5,
            normals: true,
            colors: true,
        };
        let mut long = header(&p);
        long.extend_from_slice(&[0xff; 100]);
        assert_eq!(F.parse(&long), Ok(p));
    }

    #[test]
    fn rejections() {
        let good = header(&Preamble {
            count: 9,
            normals: true,
            colors: false,
        });
        let err = |b: &[u8]| F.parse(b).unwrap_err();
        for cut in [0, 1, 4, PREAMBLE_BYTES, F.header_bytes - 1] {
            assert_eq!(
                err(&good[..cut]),
                format!("{cut} bytes, shorter than the 12-byte header")
            );
        }
        let edit = |at: usize, v: u8| {
            let mut b = good.clone();
            b[at] = v;
            b
        };
        assert_eq!(err(&edit(0, b'X')), "bad magic or version");
        assert_eq!(err(&edit(1, b'X')), "bad magic or version");
        assert_eq!(err(&edit(2, 4)), "bad magic or version");
        for flags in [4u8, 8, 0x80, 0xff, FLAG_NORMALS | 0x10] {
            assert_eq!(err(&edit(3, flags)), format!("unknown flags {flags:#x}"));
        }
    }

    #[test]
    fn le_u32_reads_little_endian() {
        let b = [9, 0x04, 0x03, 0x02, 0x01, 9];
        assert_eq!(le_u32(&b, 1), 0x0102_0304);
        assert_eq!(le_u32(&b, 2), 0x0901_0203);
    }
}
