use crate::{Channels, Error, Result};

/// What a decoder may allocate. Every decoder checks the declared size of its input against
/// these limits *before* allocating, so a 100-byte file can never make it allocate gigabytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Largest width in pixels.
    pub max_width: u32,
    /// Largest height in pixels.
    pub max_height: u32,
    /// Largest width × height.
    pub max_pixels: u64,
    /// Largest single allocation, and largest total of the buffers a decode keeps, in bytes.
    pub max_alloc_bytes: u64,
}

impl Default for Limits {
    /// 65536 × 65536 at most, 256 megapixels, 4 GiB.
    fn default() -> Self {
        Limits { max_width: 1 << 16, max_height: 1 << 16, max_pixels: 1 << 28, max_alloc_bytes: 1 << 32 }
    }
}

impl Limits {
    /// No limits at all (for trusted input only).
    pub fn none() -> Self {
        Limits { max_width: u32::MAX, max_height: u32::MAX, max_pixels: u64::MAX, max_alloc_bytes: u64::MAX }
    }

    /// Small limits for fuzzing: 4096 × 4096, 4 MP, 64 MiB.
    pub fn fuzzing() -> Self {
        Limits { max_width: 4096, max_height: 4096, max_pixels: 1 << 22, max_alloc_bytes: 1 << 26 }
    }

    /// Checks declared dimensions. Zero width or height is invalid.
    pub fn check_dimensions(&self, width: u64, height: u64) -> Result<()> {
        if width == 0 || height == 0 {
            return Err(Error::invalid(format!("image dimensions {width}x{height} are empty")));
        }
        if width > u64::from(self.max_width) || height > u64::from(self.max_height) {
            return Err(Error::limit(format!(
                "image dimensions {width}x{height} exceed the limit of {}x{}",
                self.max_width, self.max_height
            )));
        }
        // Saturating: with `Limits::none()` the dimensions may be up to 2^32-1 each.
        let pixels = width.saturating_mul(height);
        if pixels > self.max_pixels {
            return Err(Error::limit(format!("{pixels} pixels exceed the limit of {}", self.max_pixels)));
        }
        Ok(())
    }

    /// Checks one allocation of `bytes` bytes, described as `what` in the error.
    pub fn check_alloc(&self, bytes: u64, what: &str) -> Result<()> {
        if bytes > self.max_alloc_bytes {
            return Err(Error::limit(format!(
                "{what} needs {bytes} bytes, more than the limit of {}",
                self.max_alloc_bytes
            )));
        }
        Ok(())
    }

    /// Checks the dimensions and the `f32` buffer of an [`HdrImage`](crate::HdrImage) of that size.
    pub fn check_image(&self, width: u64, height: u64, channels: Channels) -> Result<()> {
        self.check_dimensions(width, height)?;
        let bytes = width.saturating_mul(height).saturating_mul(channels.count() as u64 * 4);
        self.check_alloc(bytes, "the decoded image")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_absurd_sizes_before_allocating() {
        let l = Limits::default();
        assert!(l.check_image(1 << 20, 1 << 20, Channels::Rgb).is_err());
        assert!(l.check_image(0, 5, Channels::Rgb).is_err());
        assert!(l.check_image(4096, 4096, Channels::Rgba).is_ok());
        assert!(Limits::fuzzing().check_image(4096, 4096, Channels::Rgba).is_err());
        // The largest declarable size must not overflow, even without limits.
        let max = u64::from(u32::MAX);
        assert!(Limits::none().check_image(max, max, Channels::Rgba).is_ok());
        assert!(l.check_image(max, max, Channels::Rgba).is_err());
    }
}
