//! The rendered frame as the harness sees it: an owned RGBA8 image.
//!
//! Contract:
//! - Pixels are RGBA8, row-major, top row first, tightly packed (`width * height * 4` bytes).
//! - R, G, B are sRGB-encoded colour, exactly as read back from the renderer's
//!   `Rgba8UnormSrgb` target (or written to / read from a PNG). The metrics in
//!   [`crate::metrics`] interpret them as such.
//! - Alpha is not a colour: **alpha > 0 means "a splat covered this pixel"**. The renderer
//!   clears to a background colour with alpha 0, so uncovered pixels keep the background in
//!   RGB and 0 in alpha. Hole ratio and extra coverage are computed from alpha alone.
//! - [`Image::save_png`] writes 8-bit RGBA PNGs atomically (a temporary file in the same
//!   folder, then a rename), so a crash never leaves a truncated PNG behind.
//!   [`Image::load_png`] accepts any PNG the `image` crate decodes (grey, RGB, 16-bit, …) and
//!   converts it to RGBA8; a PNG without alpha therefore loads as fully covered.
//! - [`Image::content_hash`] is 64-bit FNV-1a over `width` (u32, little-endian), `height`
//!   (u32, little-endian) and then the RGBA bytes. It is stable across platforms, runs and
//!   versions of this crate (it keys on-disk caches), and is not cryptographic.
//!
//! Errors are [`ImageError`]s that name the offending file or the sizes involved.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use ::image::ImageEncoder;

/// Errors from image I/O and from building an image from a buffer.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// An RGBA8 buffer whose length does not match its stated size.
    #[error("an RGBA8 image of {width}x{height} needs {expected} bytes, got {actual}")]
    BufferSize {
        /// Stated width.
        width: u32,
        /// Stated height.
        height: u32,
        /// `width * height * 4` (`u64::MAX` if that overflows).
        expected: u64,
        /// Actual buffer length.
        actual: u64,
    },
    /// A file could not be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// A file could not be written.
    #[error("cannot write {}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// A file is not a PNG the decoder understands.
    #[error("cannot decode {} as a PNG", path.display())]
    PngDecode {
        /// The file.
        path: PathBuf,
        /// The decoder's error.
        source: ::image::ImageError,
    },
    /// An image could not be encoded as PNG.
    #[error("cannot encode {} as a PNG", path.display())]
    PngEncode {
        /// The destination file.
        path: PathBuf,
        /// The encoder's error.
        source: ::image::ImageError,
    },
}

/// An RGBA8 image: sRGB colour, alpha > 0 marks covered pixels, row-major, top row first.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 4` bytes: R, G, B, A per pixel, rows top to bottom.
    pub rgba: Vec<u8>,
}

/// The 64-bit FNV-1a offset basis.
const FNV_OFFSET: u64 = 0xcbf2_9ce4_8422_2325;
/// The 64-bit FNV-1a prime.
const FNV_PRIME: u64 = 0x0000_0100_0000_01b3;

impl Image {
    /// An image of `width × height` pixels, all `[0, 0, 0, 0]` (black, not covered).
    ///
    /// # Panics
    /// If `width * height * 4` does not fit in memory addressing (`usize`); use
    /// [`Image::from_rgba`] for sizes that come from untrusted input.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        let len = rgba_len(width, height)
            .unwrap_or_else(|| panic!("image size {width}x{height} overflows the address space"));
        Self {
            width,
            height,
            rgba: vec![0; len],
        }
    }

    /// Wraps an RGBA8 buffer; errors unless `rgba.len() == width * height * 4`.
    pub fn from_rgba(width: u32, height: u32, rgba: Vec<u8>) -> Result<Self, ImageError> {
        match rgba_len(width, height) {
            Some(expected) if expected == rgba.len() => Ok(Self {
                width,
                height,
                rgba,
            }),
            expected => Err(ImageError::BufferSize {
                width,
                height,
                expected: expected.map_or(u64::MAX, |e| e as u64),
                actual: rgba.len() as u64,
            }),
        }
    }

    /// Number of pixels, `width * height`.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        self.rgba.len() / 4
    }

    /// The RGBA value at column `x`, row `y` (row 0 is the top).
    ///
    /// # Panics
    /// If `x >= width` or `y >= height`.
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = self.offset(x, y);
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Whether a splat covered the pixel at (`x`, `y`), i.e. its alpha is > 0.
    ///
    /// # Panics
    /// If `x >= width` or `y >= height`.
    #[must_use]
    pub fn covered(&self, x: u32, y: u32) -> bool {
        self.rgba[self.offset(x, y) + 3] > 0
    }

    /// Number of covered pixels (alpha > 0).
    #[must_use]
    pub fn coverage_count(&self) -> usize {
        self.rgba.chunks_exact(4).filter(|p| p[3] > 0).count()
    }

    /// The RGB bytes without alpha, `width * height * 3` bytes.
    #[must_use]
    pub fn to_rgb(&self) -> Vec<u8> {
        let mut rgb = Vec::with_capacity(self.pixel_count() * 3);
        for p in self.rgba.chunks_exact(4) {
            rgb.extend_from_slice(&p[..3]);
        }
        rgb
    }

    /// 64-bit FNV-1a over `width` (LE u32), `height` (LE u32) and the RGBA bytes.
    ///
    /// Stable across platforms and runs; not cryptographic.
    #[must_use]
    pub fn content_hash(&self) -> u64 {
        let header = self
            .width
            .to_le_bytes()
            .into_iter()
            .chain(self.height.to_le_bytes());
        header
            .chain(self.rgba.iter().copied())
            .fold(FNV_OFFSET, |h, b| {
                (h ^ u64::from(b)).wrapping_mul(FNV_PRIME)
            })
    }

    /// Writes the image as an 8-bit RGBA PNG, atomically (temporary file, then rename).
    pub fn save_png(&self, path: &Path) -> Result<(), ImageError> {
        let png = self.encode_png().map_err(|source| ImageError::PngEncode {
            path: path.to_path_buf(),
            source,
        })?;
        write_atomically(path, &png).map_err(|source| ImageError::Write {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads a PNG and converts it to RGBA8. Errors name the file.
    pub fn load_png(path: &Path) -> Result<Self, ImageError> {
        let bytes = fs::read(path).map_err(|source| ImageError::Read {
            path: path.to_path_buf(),
            source,
        })?;
        let decoded = ::image::load_from_memory_with_format(&bytes, ::image::ImageFormat::Png)
            .map_err(|source| ImageError::PngDecode {
                path: path.to_path_buf(),
                source,
            })?
            .into_rgba8();
        let (width, height) = decoded.dimensions();
        Self::from_rgba(width, height, decoded.into_raw())
    }

    /// The PNG encoding of this image (8-bit RGBA, default compression).
    fn encode_png(&self) -> Result<Vec<u8>, ::image::ImageError> {
        let mut png = Vec::new();
        ::image::codecs::png::PngEncoder::new(&mut png).write_image(
            &self.rgba,
            self.width,
            self.height,
            ::image::ExtendedColorType::Rgba8,
        )?;
        Ok(png)
    }

    /// Byte offset of pixel (`x`, `y`); panics when out of bounds.
    fn offset(&self, x: u32, y: u32) -> usize {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside a {}x{} image",
            self.width,
            self.height
        );
        (y as usize * self.width as usize + x as usize) * 4
    }
}

/// `width * height * 4`, or `None` on overflow.
fn rgba_len(width: u32, height: u32) -> Option<usize> {
    (width as usize)
        .checked_mul(height as usize)?
        .checked_mul(4)
}

/// Writes `bytes` to `path` atomically: a uniquely named temporary file in the same folder is
/// written, then renamed over `path`, so readers see the old file or the whole new one, never
/// a truncated one (no fsync: this guards against crashes of the process, not power loss).
/// On error the temporary file is removed.
pub(crate) fn write_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "the path names no file"))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(
        ".{}.{}.tmp",
        std::process::id(),
        COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp: PathBuf = path.with_file_name(tmp_name);
    let result = (|| {
        let mut file = fs::File::create(&tmp)?;
        file.write_all(bytes)?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        // Best effort: the temporary file may not even exist.
        let _ = fs::remove_file(&tmp);
    }
    result
}
