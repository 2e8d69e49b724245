//! `render --plot`: the figure ([`tactus_glove::plot::render_svg`]) as `.svg`, or rasterised
//! to `.png` at one pixel per SVG unit with resvg (usvg + tiny-skia, pure Rust). Text needs a
//! font: system fonts are found through fontdb; when none is found the PNG is still drawn,
//! without its text, and [`PngPlot::fonts`] says so.

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use resvg::usvg;

pub use tactus_glove::plot::render_svg;

/// What `--plot` writes, chosen by the file's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotFormat {
    /// The SVG as drawn.
    Svg,
    /// The SVG rasterised.
    Png,
}

/// `.svg` or `.png` (any case); anything else is a clear error.
pub fn format_of(path: &Path) -> Result<PlotFormat> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
    {
        Some(e) if e == "svg" => Ok(PlotFormat::Svg),
        Some(e) if e == "png" => Ok(PlotFormat::Png),
        _ => bail!(
            "--plot {}: the plot must end in .svg or .png",
            path.display()
        ),
    }
}

/// A rasterised plot.
#[derive(Debug, Clone)]
pub struct PngPlot {
    /// The PNG file's bytes (8-bit RGBA).
    pub bytes: Vec<u8>,
    /// Whether a font was found; without one the PNG has no text.
    pub fonts: bool,
}

/// Families tried for `sans-serif` when the system's configuration names none that is
/// installed (fontdb's built-in default is Arial).
const SANS: [&str; 6] = [
    "DejaVu Sans",
    "Liberation Sans",
    "Noto Sans",
    "FreeSans",
    "Arial",
    "Helvetica",
];

/// The system's fonts, with `sans-serif` mapped to an installed family. Empty if none.
fn system_fonts() -> usvg::fontdb::Database {
    use usvg::fontdb::{Family, Query};
    let mut db = usvg::fontdb::Database::new();
    db.load_system_fonts();
    let sans = Query {
        families: &[Family::SansSerif],
        ..Query::default()
    };
    if !db.is_empty() && db.query(&sans).is_none() {
        let installed = |name: &str| {
            db.faces()
                .any(|f| f.families.iter().any(|(n, _)| n.eq_ignore_ascii_case(name)))
        };
        let family = SANS
            .iter()
            .find(|n| installed(n))
            .map(|n| n.to_string())
            .or_else(|| {
                db.faces()
                    .find_map(|f| f.families.first().map(|(n, _)| n.clone()))
            });
        if let Some(family) = family {
            db.set_sans_serif_family(family);
        }
    }
    db
}

/// Rasterises an SVG from [`render_svg`] at one pixel per unit on white and encodes it as PNG.
/// Fails only if the SVG does not parse or the image is too large to allocate.
pub fn render_png(svg: &str) -> Result<PngPlot> {
    use resvg::tiny_skia;
    let fonts = system_fonts();
    let has_fonts = !fonts.is_empty();
    let opt = usvg::Options {
        font_family: "sans-serif".to_string(),
        fontdb: std::sync::Arc::new(fonts),
        ..usvg::Options::default()
    };
    let tree =
        usvg::Tree::from_str(svg, &opt).map_err(|e| anyhow!("the SVG does not parse: {e}"))?;
    let size = tree.size().to_int_size();
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height()).ok_or_else(|| {
        anyhow!(
            "a {}x{} image cannot be allocated",
            size.width(),
            size.height()
        )
    })?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(
        &tree,
        tiny_skia::Transform::identity(),
        &mut pixmap.as_mut(),
    );
    let bytes = pixmap
        .encode_png()
        .map_err(|e| anyhow!("PNG encoding: {e}"))?;
    Ok(PngPlot {
        bytes,
        fonts: has_fonts,
    })
}
