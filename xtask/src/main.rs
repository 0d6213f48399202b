//! xtask: the project's own checks, beside the tools (`cargo run -p xtask -- COMMAND`).
//!
//! `check-pictures LIST DIR`: every picture LIST names is in DIR, decodes as PNG, has the
//! size LIST gives it and is not blank; and DIR holds no PNG that LIST does not name. `make
//! smoke` runs it on the smoke scale's pictures (pipelines/pictures.txt), so a recipe that
//! stops drawing a figure, or draws an empty one, fails CI.

use anyhow::{bail, Context};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

const USAGE: &str = "usage: xtask check-pictures LIST DIR
  LIST: one picture a line, `PATH WIDTHxHEIGHT` (PATH relative to DIR; # starts a comment)";

/// A picture is blank when fewer than this share of its pixels differ from its background
/// (its most common colour): a title alone on an empty canvas of 900 x 600 inks about 0.3 %.
const MIN_INK: f64 = 0.01;

/// ... or when fewer than this share are in colour ([`COLOURED`]): a chart's axes, grid and
/// text are grey, its series coloured (a series line inks 0.7 % of a 1200 x 500 chart or more).
const MIN_COLOURED: f64 = 0.001;

/// A pixel is in colour when its channels spread by more than this (of 255).
const COLOURED: u8 = 60;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let result = match args.iter().map(String::as_str).collect::<Vec<_>>()[..] {
        ["check-pictures", list, dir] => check_pictures(Path::new(list), Path::new(dir)),
        _ => {
            eprintln!("{USAGE}");
            return ExitCode::from(2);
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("xtask: {e:#}");
            ExitCode::from(1)
        }
    }
}

/// What a picture holds, for the blank test.
#[derive(Debug, PartialEq)]
struct Ink {
    width: u32,
    height: u32,
    /// The share of pixels not of the most common colour.
    ink: f64,
    /// The share of pixels in colour ([`COLOURED`]).
    coloured: f64,
}

/// Decodes a PNG file into its size and ink.
fn ink_of(path: &Path) -> anyhow::Result<Ink> {
    let file = std::fs::File::open(path).context("opening it")?;
    let mut decoder = png::Decoder::new(std::io::BufReader::new(file));
    decoder.set_transformations(png::Transformations::normalize_to_color8());
    let mut reader = decoder.read_info().context("not a PNG")?;
    let mut buf = vec![0; reader.output_buffer_size().context("too large to decode")?];
    let frame = reader
        .next_frame(&mut buf)
        .context("its pixels do not decode")?;
    let channels = frame.color_type.samples();
    let mut counts: HashMap<&[u8], u64> = HashMap::new();
    let mut coloured = 0u64;
    for px in buf[..frame.buffer_size()].chunks_exact(channels) {
        *counts.entry(px).or_default() += 1;
        // Grey pictures (one or two channels) have no colour.
        let rgb = &px[..channels.min(3)];
        let (lo, hi) = (rgb.iter().min(), rgb.iter().max());
        coloured += u64::from(channels >= 3 && hi.zip(lo).is_some_and(|(h, l)| h - l > COLOURED));
    }
    let pixels = u64::from(frame.width) * u64::from(frame.height);
    let background = counts.values().copied().max().unwrap_or(0);
    Ok(Ink {
        width: frame.width,
        height: frame.height,
        ink: (pixels - background) as f64 / pixels.max(1) as f64,
        coloured: coloured as f64 / pixels.max(1) as f64,
    })
}

/// `WIDTHxHEIGHT`.
fn size_of(text: &str) -> Option<(u32, u32)> {
    let (w, h) = text.split_once('x')?;
    Some((w.parse().ok()?, h.parse().ok()?))
}

/// Every PNG below `dir`, as paths relative to it.
fn pngs_below(dir: &Path, rel: &Path, found: &mut Vec<PathBuf>) -> anyhow::Result<()> {
    let listing = std::fs::read_dir(dir.join(rel))
        .with_context(|| format!("reading {}", dir.join(rel).display()))?;
    for entry in listing {
        let entry = entry?;
        let path = rel.join(entry.file_name());
        if entry.file_type()?.is_dir() {
            pngs_below(dir, &path, found)?;
        } else if path.extension().is_some_and(|e| e == "png") {
            found.push(path);
        }
    }
    Ok(())
}

fn check_pictures(list: &Path, dir: &Path) -> anyhow::Result<()> {
    let text =
        std::fs::read_to_string(list).with_context(|| format!("reading {}", list.display()))?;
    let mut expected = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("").trim();
        if line.is_empty() {
            continue;
        }
        let (path, size) = match line.split_whitespace().collect::<Vec<_>>()[..] {
            [p, s] => (p, size_of(s)),
            _ => (line, None),
        };
        let Some(size) = size else {
            bail!(
                "{} line {}: '{line}' is not `PATH WIDTHxHEIGHT`",
                list.display(),
                n + 1
            );
        };
        expected.push((PathBuf::from(path), size));
    }
    let mut faults = Vec::new();
    for (path, (w, h)) in &expected {
        match ink_of(&dir.join(path)) {
            Err(e) => faults.push(format!("{}: {e:#}", path.display())),
            Ok(ink) => {
                let mut fault = |what: String| faults.push(format!("{}: {what}", path.display()));
                if (ink.width, ink.height) != (*w, *h) {
                    fault(format!("{}x{}, not {w}x{h}", ink.width, ink.height));
                }
                if ink.ink < MIN_INK || ink.coloured < MIN_COLOURED {
                    fault(format!(
                        "blank: {:.2} % of its pixels inked (at least {} %), {:.2} % in colour (at least {} %)",
                        100.0 * ink.ink,
                        100.0 * MIN_INK,
                        100.0 * ink.coloured,
                        100.0 * MIN_COLOURED
                    ));
                }
                eprintln!(
                    "xtask: {} {}x{}, {:.1} % inked, {:.2} % in colour",
                    path.display(),
                    ink.width,
                    ink.height,
                    100.0 * ink.ink,
                    100.0 * ink.coloured
                );
            }
        }
    }
    let mut found = Vec::new();
    pngs_below(dir, Path::new(""), &mut found)?;
    found.sort();
    for path in found {
        if !expected.iter().any(|(p, _)| *p == path) {
            faults.push(format!(
                "{}: a picture {} does not list",
                path.display(),
                list.display()
            ));
        }
    }
    if !faults.is_empty() {
        bail!(
            "{} of {} pictures fail:\n  {}",
            faults.len(),
            expected.len(),
            faults.join("\n  ")
        );
    }
    eprintln!(
        "xtask: {} pictures in {}: each decodes, has its size and is not blank",
        expected.len(),
        dir.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Writes a picture of `w` x `h`, every pixel `paint(x, y)`.
    fn picture(path: &Path, w: u32, h: u32, paint: impl Fn(u32, u32) -> [u8; 3]) {
        let file = std::fs::File::create(path).unwrap();
        let mut enc = png::Encoder::new(std::io::BufWriter::new(file), w, h);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        let mut writer = enc.write_header().unwrap();
        let data: Vec<u8> = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .flat_map(|(x, y)| paint(x, y))
            .collect();
        writer.write_image_data(&data).unwrap();
    }

    #[test]
    fn a_blank_a_wrong_size_a_broken_and_an_unlisted_picture_fail() {
        let dir = std::env::temp_dir().join(format!("xtask-pictures-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).unwrap();
        let colourful = |x: u32, y: u32| {
            if (x / 4 + y / 4) % 2 == 0 {
                [255, 255, 255]
            } else {
                [(x * 13 % 256) as u8, (y * 7 % 256) as u8, 90]
            }
        };
        picture(&dir.join("good.png"), 64, 48, colourful);
        picture(&dir.join("sub/blank.png"), 64, 48, |_, _| [255, 255, 255]);
        // Grey lines only: a chart's frame without its series.
        let grey = |x: u32, y: u32| match (x % 8, y % 8) {
            (0, _) | (_, 0) => [90, 90, 90],
            _ => [255, 255, 255],
        };
        picture(&dir.join("grey.png"), 64, 48, grey);
        picture(&dir.join("small.png"), 32, 48, colourful);
        std::fs::write(dir.join("broken.png"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
        let list = dir.join("list.txt");
        std::fs::write(&list, "good.png 64x48\n").unwrap();
        let all = |text: &str| {
            std::fs::write(&list, text).unwrap();
            check_pictures(&list, &dir).map_err(|e| format!("{e:#}"))
        };
        let e = all(
            "good.png 64x48\nsub/blank.png 64x48\nsmall.png 64x48\nbroken.png 1x1\ngrey.png 64x48\n",
        )
        .unwrap_err();
        assert!(
            e.contains("sub/blank.png: blank: 0.00 % of its pixels inked"),
            "{e}"
        );
        assert!(e.contains("grey.png: blank: 2"), "{e}");
        assert!(e.contains("0.00 % in colour"), "{e}");
        assert!(e.contains("small.png: 32x48, not 64x48"), "{e}");
        assert!(e.contains("broken.png: not a PNG"), "{e}");
        assert!(e.contains("4 of 5 pictures fail"), "{e}");
        let e = all("good.png 64x48\n").unwrap_err();
        assert!(e.contains("small.png: a picture"), "{e}");
        for f in ["sub/blank.png", "small.png", "broken.png", "grey.png"] {
            std::fs::remove_file(dir.join(f)).unwrap();
        }
        assert_eq!(all("# the one picture\ngood.png 64x48\n"), Ok(()));
        assert!(all("good.png 64 48\n")
            .unwrap_err()
            .contains("not `PATH WIDTHxHEIGHT`"));
        assert!(all("good.png 64x48\nmissing.png 64x48\n")
            .unwrap_err()
            .contains("missing.png: opening it"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
