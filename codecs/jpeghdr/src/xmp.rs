//! XMP (APP1 `http://ns.adobe.com/xap/1.0/`) as gain-map files use it: Adobe's `hdrgm`
//! properties (the Ultra HDR format), Google's GContainer directory, and Apple's auxiliary
//! image type and HDR headroom. Parsed as XML with namespaces (prefixes vary between writers;
//! values come as attributes or as elements, scalars or `rdf:Seq` of one or three).

use crate::metadata::GainMapMetadata;
use hdrcodec_core::{Error, Result};

/// The APP1 payload signature of a standard XMP packet.
pub const SIGNATURE: &[u8] = b"http://ns.adobe.com/xap/1.0/\0";
/// Adobe's gain-map namespace.
pub const HDRGM: &str = "http://ns.adobe.com/hdr-gain-map/1.0/";
const RDF: &str = "http://www.w3.org/1999/02/22-rdf-syntax-ns#";
const CONTAINER: &str = "http://ns.google.com/photos/1.0/container/";
const ITEM: &str = "http://ns.google.com/photos/1.0/container/item/";
const APPLE_PIXEL_INFO: &str = "http://ns.apple.com/pixeldatainfo/1.0/";
const APPLE_GAIN_MAP: &str = "http://ns.apple.com/HDRGainMap/1.0/";
/// The auxiliary image type of Apple's HDR gain map.
pub const APPLE_GAIN_MAP_URN: &str = "urn:com:apple:photo:2020:aux:hdrgainmap";

fn invalid(what: impl std::fmt::Display) -> Error {
    Error::invalid(format!("XMP: {what}"))
}

/// A parsed XMP packet.
pub struct Xmp {
    text: String,
}

/// The values of one property: one, or one per channel.
type Values = Vec<String>;

impl Xmp {
    /// Takes an APP1 payload (signature removed). Fails if it is not UTF-8 XML.
    pub fn new(payload: &[u8]) -> Result<Self> {
        // Packets are padded with whitespace and sometimes NULs after the closing wrapper.
        let end = payload.iter().rposition(|&b| b != 0).map_or(0, |p| p + 1);
        let text = std::str::from_utf8(&payload[..end]).map_err(|_| invalid("not UTF-8"))?.to_owned();
        roxmltree::Document::parse(&text).map_err(invalid)?;
        Ok(Xmp { text })
    }

    fn document(&self) -> roxmltree::Document<'_> {
        // Parsed once in `new` already: this cannot fail.
        roxmltree::Document::parse(&self.text).unwrap_or_else(|_| unreachable!("XMP was checked in Xmp::new"))
    }

    /// Every value of the property `name` in namespace `ns`, wherever it sits: an attribute of
    /// any element, or an element whose text (or whose `rdf:Seq`/`rdf:Alt`/`rdf:Bag` items)
    /// hold the value(s). The first occurrence wins.
    fn property(&self, ns: &str, name: &str) -> Option<Values> {
        let doc = self.document();
        for node in doc.descendants().filter(|n| n.is_element()) {
            if let Some(v) = node.attribute((ns, name)) {
                return Some(vec![v.trim().to_owned()]);
            }
            if node.tag_name().namespace() == Some(ns) && node.tag_name().name() == name {
                let items: Values = node
                    .descendants()
                    .filter(|n| n.is_element() && n.tag_name().namespace() == Some(RDF) && n.tag_name().name() == "li")
                    .map(|n| n.text().unwrap_or("").trim().to_owned())
                    .collect();
                if !items.is_empty() {
                    return Some(items);
                }
                return Some(vec![node.text().unwrap_or("").trim().to_owned()]);
            }
        }
        None
    }

    /// The `hdrgm:Version` the packet declares, if any (a primary image's sign that it has an
    /// Adobe gain map).
    pub fn hdrgm_version(&self) -> Option<String> {
        self.property(HDRGM, "Version").and_then(|v| v.into_iter().next())
    }

    /// The gain-map metadata of a gain-map image's hdrgm properties (Adobe's gain map
    /// specification; Ultra HDR 1.0 table), with the specification's defaults for the optional
    /// ones; `Ok(None)` if the packet has no `hdrgm:Version`.
    pub fn hdrgm_metadata(&self) -> Result<Option<GainMapMetadata>> {
        let Some(version) = self.hdrgm_version() else { return Ok(None) };
        if version != "1.0" {
            return Err(Error::unsupported(format!("hdrgm gain map version {version:?}")));
        }
        let per_channel = |name: &str, default: f64| -> Result<([f64; 3], bool)> {
            match self.property(HDRGM, name) {
                None => Ok(([default; 3], false)),
                Some(v) if v.len() == 1 => {
                    let x = number(&v[0], name)?;
                    Ok(([x; 3], false))
                }
                Some(v) if v.len() == 3 => {
                    Ok(([number(&v[0], name)?, number(&v[1], name)?, number(&v[2], name)?], true))
                }
                Some(v) => Err(invalid(format!("hdrgm:{name} has {} values", v.len()))),
            }
        };
        let scalar = |name: &str, default: Option<f64>| -> Result<f64> {
            match (self.property(HDRGM, name), default) {
                (Some(v), _) if v.len() == 1 => number(&v[0], name),
                (Some(_), _) => Err(invalid(format!("hdrgm:{name} must be one value"))),
                (None, Some(d)) => Ok(d),
                (None, None) => Err(invalid(format!("hdrgm:{name} is required and missing"))),
            }
        };
        let base_is_hdr = match self.property(HDRGM, "BaseRenditionIsHDR").as_deref() {
            None => false,
            Some([v]) if v.eq_ignore_ascii_case("true") => true,
            Some([v]) if v.eq_ignore_ascii_case("false") => false,
            Some(v) => return Err(invalid(format!("hdrgm:BaseRenditionIsHDR is {v:?}"))),
        };
        let (gain_min, m1) = per_channel("GainMapMin", 0.0)?;
        if self.property(HDRGM, "GainMapMax").is_none() {
            return Err(invalid("hdrgm:GainMapMax is required and missing"));
        }
        let (gain_max, m2) = per_channel("GainMapMax", 1.0)?;
        let (gamma, m3) = per_channel("Gamma", 1.0)?;
        let (offset_sdr, m4) = per_channel("OffsetSDR", 1.0 / 64.0)?;
        let (offset_hdr, m5) = per_channel("OffsetHDR", 1.0 / 64.0)?;
        let capacity_min = scalar("HDRCapacityMin", Some(0.0))?;
        let capacity_max = scalar("HDRCapacityMax", None)?;
        // ISO 21496-1 Annex: the base's headroom is HDRCapacityMin for an SDR base, and the
        // roles of the headrooms and offsets swap when the base is the HDR rendition.
        let (base_headroom, alternate_headroom, base_offset, alternate_offset) = if base_is_hdr {
            (capacity_max, capacity_min, offset_hdr, offset_sdr)
        } else {
            (capacity_min, capacity_max, offset_sdr, offset_hdr)
        };
        let m = GainMapMetadata {
            base_headroom,
            alternate_headroom,
            gain_min,
            gain_max,
            gamma,
            base_offset,
            alternate_offset,
            multichannel: m1 || m2 || m3 || m4 || m5,
            use_base_colour_space: true,
        };
        m.check()?;
        Ok(Some(m))
    }

    /// The GContainer directory: (semantic, length) of each item, in order (`Primary` first).
    /// Empty if the packet has none.
    pub fn container_items(&self) -> Vec<(String, Option<u64>)> {
        let doc = self.document();
        doc.descendants()
            .filter(|n| n.is_element() && n.tag_name().namespace() == Some(CONTAINER) && n.tag_name().name() == "Item")
            .map(|item| {
                // Item fields are attributes of Container:Item, or child elements of it.
                let field = |name: &str| {
                    item.attribute((ITEM, name)).map(str::to_owned).or_else(|| {
                        item.children()
                            .find(|c| c.tag_name().namespace() == Some(ITEM) && c.tag_name().name() == name)
                            .and_then(|c| c.text())
                            .map(|t| t.trim().to_owned())
                    })
                };
                (field("Semantic").unwrap_or_default(), field("Length").and_then(|l| l.trim().parse().ok()))
            })
            .collect()
    }

    /// True if the packet marks its image as Apple's HDR gain map.
    pub fn is_apple_gain_map(&self) -> bool {
        self.property(APPLE_PIXEL_INFO, "AuxiliaryImageType")
            .is_some_and(|v| v.first().map(String::as_str) == Some(APPLE_GAIN_MAP_URN))
    }

    /// Apple's `HDRGainMapHeadroom` (the linear headroom of the full gain), if written.
    pub fn apple_headroom(&self) -> Result<Option<f64>> {
        match self.property(APPLE_GAIN_MAP, "HDRGainMapHeadroom").as_deref() {
            None => Ok(None),
            Some([v]) => number(v, "HDRGainMapHeadroom").map(Some),
            Some(_) => Err(invalid("HDRGainMap:HDRGainMapHeadroom must be one value")),
        }
    }
}

/// An XMP real: decimal, optional sign and exponent ("1", "0.000000", "1.3e-2").
fn number(text: &str, name: &str) -> Result<f64> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| invalid(format!("{name} is not a number: {text:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn packet(body: &str) -> Xmp {
        let text = format!(
            r#"<?xpacket begin="" id="W5M0MpCehiHzreSzNTczkc9d"?><x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF xmlns:rdf="{RDF}">{body}</rdf:RDF></x:xmpmeta><?xpacket end="w"?>  "#
        );
        Xmp::new(text.as_bytes()).unwrap()
    }

    #[test]
    fn hdrgm_attributes_and_sequences() {
        // Attribute form with an unusual prefix, as Ultra HDR writers do.
        let x = packet(&format!(
            r#"<rdf:Description xmlns:g="{HDRGM}" g:Version="1.0" g:GainMapMax="2.5" g:HDRCapacityMax="2.5" g:OffsetSDR="0"/>"#
        ));
        let m = x.hdrgm_metadata().unwrap().unwrap();
        assert_eq!(
            (m.gain_max, m.alternate_headroom, m.base_offset, m.alternate_offset),
            ([2.5; 3], 2.5, [0.0; 3], [1.0 / 64.0; 3])
        );
        assert!(!m.multichannel);
        // Element form with per-channel sequences, as Photoshop writes, and an HDR base.
        let x = packet(&format!(
            r#"<rdf:Description xmlns:hdrgm="{HDRGM}" hdrgm:Version="1.0" hdrgm:BaseRenditionIsHDR="True" hdrgm:HDRCapacityMax="1.3">
               <hdrgm:GainMapMax><rdf:Seq><rdf:li>1.2</rdf:li><rdf:li>1.25</rdf:li><rdf:li>1.3</rdf:li></rdf:Seq></hdrgm:GainMapMax>
               <hdrgm:Gamma>0.9</hdrgm:Gamma></rdf:Description>"#
        ));
        let m = x.hdrgm_metadata().unwrap().unwrap();
        assert_eq!(
            (m.gain_max, m.gamma, m.base_headroom, m.alternate_headroom),
            ([1.2, 1.25, 1.3], [0.9; 3], 1.3, 0.0)
        );
        assert!(m.multichannel);
    }

    #[test]
    fn missing_or_broken_hdrgm_values_are_errors() {
        let x = packet(&format!(
            r#"<rdf:Description xmlns:hdrgm="{HDRGM}" hdrgm:Version="1.0" hdrgm:HDRCapacityMax="2"/>"#
        ));
        assert!(x.hdrgm_metadata().is_err());
        let x = packet(&format!(
            r#"<rdf:Description xmlns:hdrgm="{HDRGM}" hdrgm:Version="1.0" hdrgm:GainMapMax="x" hdrgm:HDRCapacityMax="2"/>"#
        ));
        assert!(x.hdrgm_metadata().is_err());
        assert!(packet("<rdf:Description/>").hdrgm_metadata().unwrap().is_none());
        assert!(Xmp::new(b"<a><b></a>").is_err());
    }

    #[test]
    fn gcontainer_items() {
        let x = packet(&format!(
            r#"<rdf:Description xmlns:Container="{CONTAINER}" xmlns:Item="{ITEM}"><Container:Directory><rdf:Seq>
               <rdf:li rdf:parseType="Resource"><Container:Item Item:Semantic="Primary" Item:Mime="image/jpeg"/></rdf:li>
               <rdf:li rdf:parseType="Resource"><Container:Item Item:Semantic="GainMap" Item:Mime="image/jpeg" Item:Length="1234"/></rdf:li>
               </rdf:Seq></Container:Directory></rdf:Description>"#
        ));
        assert_eq!(x.container_items(), [("Primary".to_owned(), None), ("GainMap".to_owned(), Some(1234))]);
    }
}
