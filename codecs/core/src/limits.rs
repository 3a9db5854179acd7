use crate::{Channels, Error, Result};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// What a decoder may allocate. Every decoder checks the declared size of its input against
/// these limits *before* allocating, so a 100-byte file can never make it allocate gigabytes.
///
/// Besides the per-allocation checks, a `Limits` carries an allocation budget: decoders
/// [`charge`](Limits::charge) each large buffer they hold (the image, planes, block rows) and
/// the charge is returned when the buffer goes. Clones share the budget, so a caller that
/// passes clones of one `Limits` to several decodes running at once (a batch) bounds their sum.
/// Construct with [`Limits::default`], [`Limits::none`] or [`Limits::fuzzing`] and set the
/// fields you want to change (the struct is `#[non_exhaustive]`).
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct Limits {
    /// Largest width in pixels.
    pub max_width: u32,
    /// Largest height in pixels.
    pub max_height: u32,
    /// Largest width × height.
    pub max_pixels: u64,
    /// Largest single allocation, and largest total of the buffers a decode keeps, in bytes.
    pub max_alloc_bytes: u64,
    /// Bytes charged and not yet returned, shared by clones.
    in_use: Arc<AtomicU64>,
    /// The most bytes ever in use at once, shared by clones.
    peak: Arc<AtomicU64>,
}

impl PartialEq for Limits {
    /// Equal limits (the budgets in use are not compared).
    fn eq(&self, o: &Self) -> bool {
        (self.max_width, self.max_height, self.max_pixels, self.max_alloc_bytes)
            == (o.max_width, o.max_height, o.max_pixels, o.max_alloc_bytes)
    }
}
impl Eq for Limits {}

impl Default for Limits {
    /// 65536 × 65536 at most, 256 megapixels, 4 GiB.
    fn default() -> Self {
        Limits::new(1 << 16, 1 << 16, 1 << 28, 1 << 32)
    }
}

impl Limits {
    /// Limits of these sizes, with a budget of its own.
    pub fn new(max_width: u32, max_height: u32, max_pixels: u64, max_alloc_bytes: u64) -> Self {
        Limits { max_width, max_height, max_pixels, max_alloc_bytes, in_use: Arc::default(), peak: Arc::default() }
    }

    /// No limits at all (for trusted input only).
    pub fn none() -> Self {
        Limits::new(u32::MAX, u32::MAX, u64::MAX, u64::MAX)
    }

    /// Small limits for fuzzing: 4096 × 4096, 4 MP, 64 MiB.
    pub fn fuzzing() -> Self {
        Limits::new(4096, 4096, 1 << 22, 1 << 26)
    }

    /// The same limits with at most `pixels` pixels.
    pub fn with_max_pixels(mut self, pixels: u64) -> Self {
        self.max_pixels = pixels;
        self
    }

    /// The same limits with at most `bytes` bytes allocated.
    pub fn with_max_alloc_bytes(mut self, bytes: u64) -> Self {
        self.max_alloc_bytes = bytes;
        self
    }

    /// The same limits with a fresh budget of their own (not shared with `self`).
    pub fn with_own_budget(&self) -> Self {
        Limits { in_use: Arc::default(), peak: Arc::default(), ..self.clone() }
    }

    /// Bytes charged against the budget and not yet returned.
    pub fn in_use(&self) -> u64 {
        self.in_use.load(Ordering::Relaxed)
    }

    /// The most bytes charged at once since the budget was made: what the decodes sharing it
    /// really held at their peak (for planning a batch, and for tests of a decoder's memory).
    pub fn peak(&self) -> u64 {
        self.peak.load(Ordering::Relaxed)
    }

    /// Charges `bytes` (a buffer about to be allocated, described as `what`) against the
    /// budget shared by this `Limits` and its clones; fails, charging nothing, if the total in
    /// use would exceed `max_alloc_bytes`. The charge is returned when the [`Allocation`] is
    /// dropped: keep it alive as long as the buffer.
    pub fn charge(&self, bytes: u64, what: &str) -> Result<Allocation> {
        let mut current = self.in_use.load(Ordering::Relaxed);
        loop {
            let total = current.saturating_add(bytes);
            if total > self.max_alloc_bytes {
                return Err(Error::limit(if current == 0 {
                    format!("{what} needs {bytes} bytes, more than the limit of {}", self.max_alloc_bytes)
                } else {
                    format!(
                        "{what} needs {bytes} bytes; with {current} already in use that exceeds the limit of {}",
                        self.max_alloc_bytes
                    )
                }));
            }
            match self.in_use.compare_exchange_weak(current, total, Ordering::AcqRel, Ordering::Relaxed) {
                Ok(_) => {
                    self.peak.fetch_max(total, Ordering::Relaxed);
                    return Ok(Allocation { in_use: Arc::clone(&self.in_use), bytes });
                }
                Err(now) => current = now,
            }
        }
    }

    /// Charges the `f32` buffer of a decoded image of this size, after checking its dimensions.
    pub fn charge_image(&self, width: u64, height: u64, channels: Channels) -> Result<Allocation> {
        self.check_dimensions(width, height)?;
        let bytes = width.saturating_mul(height).saturating_mul(channels.count() as u64 * 4);
        self.charge(bytes, "the decoded image")
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

/// A charge against a [`Limits`] budget, returned when dropped.
#[derive(Debug)]
#[must_use = "the charge is returned as soon as the Allocation is dropped"]
pub struct Allocation {
    in_use: Arc<AtomicU64>,
    bytes: u64,
}

impl Allocation {
    /// The bytes charged.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

impl Drop for Allocation {
    fn drop(&mut self) {
        self.in_use.fetch_sub(self.bytes, Ordering::AcqRel);
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

    #[test]
    fn the_budget_is_shared_by_clones_and_returned_on_drop() {
        let l = Limits::default().with_max_alloc_bytes(1000);
        let a = l.charge(600, "the planes").unwrap();
        let other = l.clone();
        let e = other.charge(500, "the image").unwrap_err().to_string();
        assert!(e.contains("the image needs 500 bytes; with 600 already in use"), "{e}");
        assert_eq!(l.in_use(), 600);
        // A fresh budget is not affected.
        assert!(l.with_own_budget().charge(1000, "x").is_ok());
        drop(a);
        assert_eq!(other.in_use(), 0);
        let b = other.charge_image(8, 8, Channels::Rgb).unwrap();
        assert_eq!(b.bytes(), 8 * 8 * 3 * 4);
        assert!(other.charge_image(10, 10, Channels::Rgb).is_err());
        drop(b);
        assert!(l.charge(1001, "y").is_err() && l.in_use() == 0);
    }
}
