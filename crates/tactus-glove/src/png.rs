//! `render --plot` as a file (the `png` feature): the figure ([`crate::plot::render_svg`])
//! as `.svg`, or rasterised to `.png` at one pixel per SVG unit with resvg (usvg +
//! tiny-skia, pure Rust). Text needs a font: system fonts are found through fontdb; when
//! none is found the PNG is still drawn, without its text, and [`PlotBytes::fonts`] says so.
//!
//! ```
//! use tactus_glove::png::{plot_bytes, PlotFormat};
//! use tactus_glove::{Features, Pattern};
//! let pattern = Pattern::from_json_str(include_str!("../tests/fixtures/pattern-v1.json")).unwrap();
//! let features = Features::from_json_str(include_str!("../tests/fixtures/features-v1.json")).unwrap();
//! let svg = plot_bytes(&pattern, &features, PlotFormat::Svg).unwrap();
//! assert!(svg.bytes.starts_with(b"<svg"));
//! ```

use std::path::Path;

use resvg::usvg;

use crate::{Features, Pattern};

/// What a plot file holds, chosen by its extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PlotFormat {
    /// The SVG as drawn.
    Svg,
    /// The SVG rasterised.
    Png,
}

impl PlotFormat {
    /// `.svg` or `.png` (any case); `None` for anything else.
    pub fn of(path: &Path) -> Option<PlotFormat> {
        crate::atomic::by_extension(path, &[("svg", PlotFormat::Svg), ("png", PlotFormat::Png)])
    }
}

/// Why a plot could not be drawn.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// The SVG did not parse (a bug in [`crate::plot::render_svg`]).
    #[error("the SVG does not parse: {0}")]
    Parse(#[source] usvg::Error),
    /// The image is too large to allocate.
    #[error("a {0}x{1} image cannot be allocated")]
    TooLarge(u32, u32),
    /// PNG encoding failed.
    #[error("PNG encoding: {0}")]
    Encode(String),
}

/// A drawn plot.
#[derive(Debug, Clone)]
pub struct PlotBytes {
    /// The file's bytes (SVG text, or PNG 8-bit RGBA).
    pub bytes: Vec<u8>,
    /// Whether a font was found (always true for SVG); without one the PNG has no text.
    pub fonts: bool,
}

/// The plot of a render as `format`'s bytes.
pub fn plot_bytes(
    pattern: &Pattern,
    features: &Features,
    format: PlotFormat,
) -> Result<PlotBytes, PlotError> {
    let svg = crate::plot::render_svg(pattern, features);
    match format {
        PlotFormat::Svg => Ok(PlotBytes {
            bytes: svg.into_bytes(),
            fonts: true,
        }),
        PlotFormat::Png => render_png(&svg),
    }
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

/// Rasterises an SVG from [`crate::plot::render_svg`] at one pixel per unit on white and
/// encodes it as PNG. Fails only if the SVG does not parse or the image is too large to
/// allocate.
pub fn render_png(svg: &str) -> Result<PlotBytes, PlotError> {
    use resvg::tiny_skia;
    let fonts = system_fonts();
    let has_fonts = !fonts.is_empty();
    let opt = usvg::Options {
        font_family: "sans-serif".to_string(),
        fontdb: std::sync::Arc::new(fonts),
        ..usvg::Options::default()
    };
    let tree = usvg::Tree::from_str(svg, &opt).map_err(PlotError::Parse)?;
    let size = tree.size().to_int_size();
    let mut pixmap = tiny_skia::Pixmap::new(size.width(), size.height())
        .ok_or(PlotError::TooLarge(size.width(), size.height()))?;
    pixmap.fill(tiny_skia::Color::WHITE);
    resvg::render(
        &tree,
        tiny_skia::Transform::identity(),
        &mut pixmap.as_mut(),
    );
    let bytes = pixmap
        .encode_png()
        .map_err(|e| PlotError::Encode(e.to_string()))?;
    Ok(PlotBytes {
        bytes,
        fonts: has_fonts,
    })
}
