use crate::{Error, HdrImage, Limits, Result};
use std::str::FromStr;

/// The one trait every codec of the family implements (object-safe), so that the CLI, the
/// container, fuzzers and benches can treat all codecs alike. Each codec crate also offers a
/// typed API of its own with an options struct.
pub trait ImageCodec: Send + Sync {
    /// Short stable name: `"rgbe"`, `"logluv32"`, `"bc6h"`, `"exr"`, ...
    fn name(&self) -> &'static str;
    /// Stable four-byte id written into `.hdrc` files.
    fn id(&self) -> [u8; 4];
    /// File extensions (lower case, without the dot) this codec writes and reads.
    fn extensions(&self) -> &'static [&'static str];
    /// Cheap magic-number test on the first bytes of a file.
    fn sniff(&self, head: &[u8]) -> bool;
    /// Decodes a whole file held in memory. Never panics; checks `limits` before allocating.
    fn decode(&self, data: &[u8], limits: &Limits) -> Result<HdrImage>;
    /// Encodes an image to a whole file.
    fn encode(&self, image: &HdrImage, settings: &EncodeSettings) -> Result<Vec<u8>>;
}

/// What every encoder understands, plus codec-specific `key=value` options that the codec
/// parses itself (an unknown key is an error, see [`EncodeSettings::check_options`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct EncodeSettings {
    /// 0-100; each lossy codec maps it onto its own quantiser. Lossless codecs ignore it.
    pub quality: u8,
    /// 0-9: 0 is the fastest encode, 9 the most thorough search. Default 5.
    pub effort: u8,
    /// Worker threads; 0 means one per core.
    pub threads: usize,
    /// Codec-specific options in the order given.
    pub options: Vec<(String, String)>,
}

impl Default for EncodeSettings {
    fn default() -> Self {
        EncodeSettings { quality: 90, effort: 5, threads: 0, options: Vec::new() }
    }
}

impl EncodeSettings {
    /// Largest `effort` value.
    pub const MAX_EFFORT: u8 = 9;

    /// Adds a codec-specific option.
    pub fn with_option(mut self, key: impl Into<String>, value: impl Into<String>) -> Self {
        self.options.push((key.into(), value.into()));
        self
    }

    /// Parses `key=value` as given on a command line.
    pub fn push_option_str(&mut self, kv: &str) -> Result<()> {
        let (k, v) =
            kv.split_once('=').ok_or_else(|| Error::invalid(format!("option '{kv}' is not of the form key=value")))?;
        self.options.push((k.trim().to_string(), v.trim().to_string()));
        Ok(())
    }

    /// Fails with a clear error naming the codec and its known keys if any option is unknown.
    pub fn check_options(&self, codec: &str, known: &[&str]) -> Result<()> {
        for (k, _) in &self.options {
            if !known.contains(&k.as_str()) {
                let list = if known.is_empty() { "none".to_string() } else { known.join(", ") };
                return Err(Error::invalid(format!("unknown option '{k}' for codec {codec} (known options: {list})")));
            }
        }
        Ok(())
    }

    /// The last value given for `key`, if any.
    pub fn option(&self, key: &str) -> Option<&str> {
        self.options.iter().rev().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// The value of `key` parsed as `T`, with a clear error if it does not parse.
    pub fn parse_option<T: FromStr>(&self, key: &str) -> Result<Option<T>> {
        match self.option(key) {
            None => Ok(None),
            Some(v) => {
                v.parse().map(Some).map_err(|_| Error::invalid(format!("option {key}={v}: cannot parse the value")))
            }
        }
    }

    /// A boolean option: `true/false`, `yes/no`, `on/off`, `1/0`.
    pub fn bool_option(&self, key: &str) -> Result<Option<bool>> {
        match self.option(key) {
            None => Ok(None),
            Some(v) => match v.to_ascii_lowercase().as_str() {
                "true" | "yes" | "on" | "1" => Ok(Some(true)),
                "false" | "no" | "off" | "0" => Ok(Some(false)),
                _ => Err(Error::invalid(format!("option {key}={v}: expected true or false"))),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_options_are_named() {
        let s = EncodeSettings::default().with_option("mips", "true").with_option("bogus", "1");
        let err = s.check_options("bc6h", &["mips", "signed"]).unwrap_err().to_string();
        assert!(err.contains("'bogus'") && err.contains("bc6h") && err.contains("mips, signed"), "{err}");
        assert_eq!(s.bool_option("mips").unwrap(), Some(true));
        assert!(s.parse_option::<u32>("bogus").unwrap() == Some(1));
    }

    #[test]
    fn trait_is_object_safe() {
        fn _takes(_: &dyn ImageCodec) {}
    }
}
