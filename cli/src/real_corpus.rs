//! `hdrcodec bench --corpus shared`: the shared corpus of real HDR images (`../shared/corpus`,
//! or `$HDRCODEC_CORPUS`), and `--crop WxH`, which keeps a run on it tractable.
//!
//! The corpus's `MANIFEST.tsv` says what each file is. The bench takes its **HDR stills in the
//! scene-linear interchange formats**: the rows under `exr/` and `hdr/` whose `how_produced`
//! starts with "original" (the published files, not the corpus's own re-encodes such as
//! `StillLife_dwaa.exr`); the other folders hold encodings of those same pictures (`dds/`,
//! `jxr/`, `tiff/StillLife_logluv32.tif`, `jpeghdr/`), gain-map JPEGs whose HDR is a
//! reconstruction, and video.

use crate::bench::Input;
use hdrcodec::core::{Error, HdrImage, Result};
use std::path::{Path, PathBuf};

/// The folders whose original files are the bench's stills.
const STILL_FOLDERS: [&str; 2] = ["exr/", "hdr/"];

/// The shared corpus directory: `$HDRCODEC_CORPUS`, else `../shared/corpus` from the working
/// directory, else from the source tree this binary was built from; the first that has a
/// `MANIFEST.tsv`.
pub fn dir() -> Result<PathBuf> {
    let candidates: Vec<PathBuf> = match std::env::var_os("HDRCODEC_CORPUS") {
        Some(d) => vec![PathBuf::from(d)],
        None => {
            vec![PathBuf::from("../shared/corpus"), Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/corpus")]
        }
    };
    let found = candidates.iter().find(|d| d.join("MANIFEST.tsv").is_file());
    // Shown in the report: `../../` steps resolved where the path exists.
    found.map(|d| d.canonicalize().unwrap_or_else(|_| d.clone())).ok_or_else(|| {
        let tried: Vec<String> = candidates.iter().map(|d| d.display().to_string()).collect();
        Error::invalid(format!(
            "no shared corpus (a directory with MANIFEST.tsv) at {}; set HDRCODEC_CORPUS",
            tried.join(" or ")
        ))
    })
}

/// The still images a MANIFEST.tsv lists (see the module notes), as paths relative to its
/// directory, in the manifest's order. The header must name the `path` and `how_produced`
/// columns.
pub fn stills(manifest: &str) -> Result<Vec<String>> {
    let mut lines = manifest.lines();
    let header: Vec<&str> = lines.next().unwrap_or_default().split('\t').collect();
    let column = |name: &str| {
        header
            .iter()
            .position(|c| *c == name)
            .ok_or_else(|| Error::invalid(format!("MANIFEST.tsv has no '{name}' column")))
    };
    let (path, how) = (column("path")?, column("how_produced")?);
    Ok(lines
        .map(|l| l.split('\t').collect::<Vec<_>>())
        .filter(|cells| cells.get(how).is_some_and(|h| h.starts_with("original")))
        .filter_map(|cells| cells.get(path).map(|p| p.to_string()))
        .filter(|p| STILL_FOLDERS.iter().any(|f| p.starts_with(f)))
        .collect())
}

/// The files of [`stills`] in the corpus at `dir`.
pub fn still_files(dir: &Path) -> Result<Vec<PathBuf>> {
    let manifest = std::fs::read_to_string(dir.join("MANIFEST.tsv"))
        .map_err(|e| Error::Io(std::io::Error::new(e.kind(), format!("{}/MANIFEST.tsv: {e}", dir.display()))))?;
    let files: Vec<PathBuf> = stills(&manifest)?.into_iter().map(|p| dir.join(p)).collect();
    if files.is_empty() {
        return Err(Error::invalid(format!("{}/MANIFEST.tsv lists no original exr/ or hdr/ file", dir.display())));
    }
    Ok(files)
}

/// Parses a `WxH` size given to the option `flag` (`--crop`, `--video-size`; both at least 1).
pub fn parse_size(flag: &str, text: &str) -> Result<(u32, u32)> {
    let bad = || Error::invalid(format!("{flag} wants WIDTHxHEIGHT (e.g. 512x512), not '{text}'"));
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(bad)?;
    let (w, h) = (w.trim().parse::<u32>().map_err(|_| bad())?, h.trim().parse::<u32>().map_err(|_| bad())?);
    if w == 0 || h == 0 {
        return Err(bad());
    }
    Ok((w, h))
}

/// The centre `width` × `height` window of `image` (each side at most the image's).
pub fn centre_crop(image: &HdrImage, width: u32, height: u32) -> Result<HdrImage> {
    let (w, h) = (width.min(image.width()), height.min(image.height()));
    let (x0, y0) = ((image.width() - w) / 2, (image.height() - h) / 2);
    let n = image.channels().count();
    let row = image.width() as usize * n;
    let mut samples = Vec::with_capacity(w as usize * h as usize * n);
    for y in y0 as usize..(y0 + h) as usize {
        let start = y * row + x0 as usize * n;
        samples.extend_from_slice(&image.samples()[start..start + w as usize * n]);
    }
    HdrImage::new(w, h, image.channels(), samples, image.color.clone())
}

/// Crops every input larger than `width` × `height` to its centre window, naming it
/// `NAME@cWxH` so that no row passes for the whole image.
pub fn crop_inputs(inputs: &mut [Input], (width, height): (u32, u32)) -> Result<()> {
    for input in inputs.iter_mut().filter(|i| i.image.width() > width || i.image.height() > height) {
        input.image = centre_crop(&input.image, width, height)?;
        input.name = format!("{}@c{}x{}", input.name, input.image.width(), input.image.height());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use hdrcodec::core::Channels;

    #[test]
    fn the_stills_are_the_original_exr_and_hdr_files() {
        let manifest = "path\tformat\thow_produced\n\
            dds/Desk.dds\tDDS\toriginal (copy)\n\
            exr/Desk.exr\tEXR\toriginal (byte-identical copy of source file)\n\
            exr/Desk_dwaa.exr\tEXR\toiiotool ... (lossy)\n\
            hdr/hall.hdr\tRGBE\toriginal\n\
            jxr/hall.jxr\tJXR\tJxrEncApp ...\n";
        assert_eq!(stills(manifest).unwrap(), ["exr/Desk.exr", "hdr/hall.hdr"]);
        assert!(stills("file\tformat\n").is_err());
    }

    #[test]
    fn the_shared_corpus_manifest_gives_its_photographs() {
        // The real manifest, when the corpus is here (tests/ checks it in CI).
        let Ok(dir) = dir() else { return };
        let files = still_files(&dir).unwrap();
        let names: Vec<String> =
            files.iter().map(|p| p.strip_prefix(&dir).unwrap().to_string_lossy().into_owned()).collect();
        assert!(names.contains(&"exr/Desk.exr".to_string()) && names.contains(&"hdr/mpi_atrium_3.hdr".to_string()));
        assert!(!names.iter().any(|n| n.contains("dwaa") || n.starts_with("jxr/")), "{names:?}");
        assert!(files.iter().all(|f| f.is_file()), "{files:?}");
    }

    #[test]
    fn crops_are_centred_and_sizes_are_parsed() {
        let samples: Vec<f32> = (0..5 * 4).flat_map(|i| [i as f32, 0.0, 1.0]).collect();
        let img = HdrImage::new(5, 4, Channels::Rgb, samples, Default::default()).unwrap();
        let c = centre_crop(&img, 3, 2).unwrap();
        assert_eq!((c.width(), c.height()), (3, 2));
        // Window at (1, 1): pixels 6, 7, 8 then 11, 12, 13.
        let firsts: Vec<f32> = c.samples().chunks(3).map(|p| p[0]).collect();
        assert_eq!(firsts, [6.0, 7.0, 8.0, 11.0, 12.0, 13.0]);
        assert_eq!(centre_crop(&img, 9, 9).unwrap().samples(), img.samples());
        let mut inputs = vec![Input { name: "a.exr".into(), image: img }];
        crop_inputs(&mut inputs, (3, 9)).unwrap();
        assert_eq!(inputs[0].name, "a.exr@c3x4");
        assert_eq!(parse_size("--crop", "512x256").unwrap(), (512, 256));
        for bad in ["512", "0x5", "ax5", "5x"] {
            assert!(parse_size("--crop", bad).is_err(), "{bad}");
        }
    }
}
