//! RGBA8 images (temporary minimal version; replaced by the metrics branch).

/// An RGBA8 image, sRGB colour, alpha > 0 = covered.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Pixels.
    pub rgba: Vec<u8>,
}
