//! The fuzz targets: what each one decodes (its seeds are built in [`crate::seeds`], its
//! inputs made in [`crate::inputs`], and it is driven in [`crate::execute`]).

use methods::MethodKind;

/// Every target, in the order `all` runs them.
pub const ALL: [Target; 18] = [
    Target::PlyAscii,
    Target::PlyBinary,
    Target::Las,
    Target::Laz,
    Target::Pcd,
    Target::E57,
    Target::Sbc,
    Target::SceneToml,
    Target::PathToml,
    Target::Method(MethodKind::Full),
    Target::Method(MethodKind::Qsplat),
    Target::Method(MethodKind::Spt),
    Target::Method(MethodKind::Lpc),
    Target::Method(MethodKind::Mwkd),
    Target::LpcCloud,
    Target::MwkdNode,
    Target::Repo,
    Target::Http,
];

/// A fuzz target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// `scenes::ply::read` on ascii PLY files.
    PlyAscii,
    /// `scenes::ply::read` on binary PLY files (both byte orders).
    PlyBinary,
    /// `scenes::las::read` on uncompressed LAS (1.2 and 1.4).
    Las,
    /// `scenes::las::read` on LAZ (pointwise and layered chunks).
    Laz,
    /// `scenes::pcd::read` on PCD files (ascii, binary, binary_compressed).
    Pcd,
    /// `scenes::e57::read` on E57 files (the `e57` crate).
    E57,
    /// `scenes::colfile::open` on column files.
    Sbc,
    /// `SceneSpec::parse` on scene `.toml` files.
    SceneToml,
    /// `Keyframes::from_toml` on camera path files, then the cameras of the path.
    PathToml,
    /// A method's build directory: one file mutated, then `MethodKind::open` and frames.
    Method(MethodKind),
    /// `lpc::cloud::decode` on decompressed LPC clouds.
    LpcCloud,
    /// `mwkd::codec::decode` on decompressed MWKD nodes.
    MwkdNode,
    /// `store::Repository::read` (checksum, LZO) then the method's decoder.
    Repo,
    /// `harness::remote::HttpFile::get_range` on a mutated HTTP answer, then the chunk
    /// ([`crate::http`]).
    Http,
    /// Not a decoder: checks the supervision itself (a panic at input 3, an abort at 5, a
    /// panic on another thread at 6, a hang at 7). Not part of `all`.
    SelfTest,
}

impl Target {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::PlyAscii => "ply-ascii",
            Target::PlyBinary => "ply-binary",
            Target::Las => "las",
            Target::Laz => "laz",
            Target::Pcd => "pcd",
            Target::E57 => "e57",
            Target::Sbc => "sbc",
            Target::SceneToml => "scene-toml",
            Target::PathToml => "path-toml",
            Target::Method(k) => k.name(),
            Target::LpcCloud => "lpc-cloud",
            Target::MwkdNode => "mwkd-node",
            Target::Repo => "repo",
            Target::Http => "http",
            Target::SelfTest => "selftest",
        }
    }

    /// The target called `name`.
    pub fn from_name(name: &str) -> Option<Target> {
        ALL.iter()
            .copied()
            .chain([Target::SelfTest])
            .find(|t| t.name() == name)
    }

    /// What the target covers (for `--list` and the README).
    pub fn describe(self) -> &'static str {
        match self {
            Target::PlyAscii => "PLY reader, ascii bodies: header lines, counts, tokens, lines",
            Target::PlyBinary => {
                "PLY reader, binary LE/BE: header counts and types, records, lists"
            }
            Target::Las => "LAS reader (las crate): header fields, VLRs, EVLRs, point records",
            Target::Laz => "LAZ reader (laz crate): laszip VLR, chunk table, chunks, layers",
            Target::Pcd => "PCD reader: header lines, ascii/binary/LZF-compressed bodies",
            Target::E57 => "E57 reader (e57 crate): pages and checksums, XML, binary sections",
            Target::Sbc => "column file (.sbc) open: header fields (checksum resealed), columns",
            Target::SceneToml => "scene .toml parsing (SceneSpec::parse), small generators loaded",
            Target::PathToml => "keyframe path .toml parsing and validation, cameras evaluated",
            Target::Method(_) => {
                "a build directory: one file mutated (checksums resealed), open + frames + chunks"
            }
            Target::LpcCloud => "LPC cloud decoder (lpc::cloud::decode) on raw chunk bytes",
            Target::MwkdNode => "MWKD node decoder (mwkd::codec::decode) on raw chunk bytes",
            Target::Repo => "repository chunks: bounds, checksum (resealed), LZO, then decode",
            Target::Http => {
                "HTTP range answers (ureq client, our checks), then LZO and the LPC decoder"
            }
            Target::SelfTest => "the supervisor itself: a panic, an abort, a thread panic, a hang",
        }
    }
}
