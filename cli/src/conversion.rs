//! What `convert` and `batch` share: the encoder settings built from the command line, and the
//! routing of `--opt key=value` between the input's decoder and the output's encoder.

use hdrcodec::core::{DecodeOptions, EncodeSettings, ImageCodec, Limits, Result, ThreadPool};

/// The settings of a conversion before the input is known: quality, effort, the one thread
/// pool, and the `--opt` pairs still to be split between decoder and encoder.
#[derive(Clone, Debug)]
pub struct ConversionSettings {
    base: EncodeSettings,
    pairs: Vec<(String, String)>,
}

impl ConversionSettings {
    /// Checks the form of every `key=value` option now, before any file is read.
    pub fn new(quality: Option<u8>, effort: Option<u8>, pool: ThreadPool, opts: &[String]) -> Result<Self> {
        let mut base = EncodeSettings::default();
        if let Some(q) = quality {
            base.quality = q;
        }
        if let Some(e) = effort {
            base.effort = e;
        }
        base.pool = pool;
        let pairs = opts.iter().map(|kv| hdrcodec::core::split_option(kv)).collect::<Result<Vec<_>>>()?;
        Ok(ConversionSettings { base, pairs })
    }

    /// The decode options and encode settings for an input that `decoder` reads: the keys the
    /// decoder knows are its own (a gain-map JPEG's `headroom`); the encoder checks the rest.
    /// Both use the same pool.
    pub fn for_decoder(&self, decoder: &dyn ImageCodec, limits: Limits) -> (DecodeOptions, EncodeSettings) {
        let (decode, encode): (Vec<_>, Vec<_>) =
            self.pairs.iter().cloned().partition(|(k, _)| decoder.decode_option_keys().contains(&k.as_str()));
        let mut options = DecodeOptions::new(limits).with_pool(self.base.pool.clone());
        options.options = decode;
        let mut settings = self.base.clone();
        settings.options = encode;
        (options, settings)
    }
}
