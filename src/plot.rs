//! Charts (plotters) as SVG or PNG: series of points on linear or log axes,
//! optionally joined, with a legend. Used by `whitted bench` (and the
//! speed-against-accuracy chart). Text needs a TrueType font: the first of
//! the usual system fonts that exists (DejaVu Sans, Liberation Sans, ...,
//! or what `fc-match sans-serif` names), or the file `WHITTED_FONT` names
//! (then that one only); without one, plotting fails with a message saying
//! which package to install, and the commands check that before their work
//! (`ready`).

use anyhow::{anyhow, bail, Context, Result};
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// One series of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Join the points with a line.
    pub line: bool,
    /// Mark these points (indices into `points`) with a ring (e.g. a Pareto front).
    pub marked: Vec<usize>,
    /// A fixed colour (RGB) instead of the palette's next one, e.g. black
    /// for a reference line.
    pub color: Option<(u8, u8, u8)>,
}

impl Series {
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
            line: true,
            marked: Vec::new(),
            color: None,
        }
    }
}

/// A chart: title, axes and series.
#[derive(Clone, Debug, Default)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    pub series: Vec<Series>,
    /// Names for integer x positions (a categorical axis): x = 0, 1, ...
    pub x_categories: Vec<String>,
}

const SIZE: (u32, u32) = (1000, 640);

const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/liberation/LiberationSans-Regular.ttf",
    "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
    "/Library/Fonts/Arial.ttf",
    "C:\\Windows\\Fonts\\arial.ttf",
];

/// The variable that names the charts' font, overriding the search.
pub const FONT_ENV: &str = "WHITTED_FONT";

/// Checks, before a command's work, that the chart it was asked for (by
/// `flag`, to `path`) can have its text: a clear error naming both now
/// rather than after a long benchmark.
pub fn ready(flag: &str, path: &Path) -> Result<()> {
    font().map_err(|e| anyhow!("{flag} {}: {e}", path.display()))
}

/// Registers a system TrueType font as plotters' "sans-serif", once.
fn font() -> Result<()> {
    static FONT: OnceLock<Result<PathBuf, String>> = OnceLock::new();
    let r = FONT.get_or_init(|| {
        if let Some(p) = std::env::var_os(FONT_ENV).filter(|v| !v.is_empty()) {
            let p = PathBuf::from(p);
            let bytes = std::fs::read(&p)
                .map_err(|e| format!("{FONT_ENV}={}: cannot read: {e}", p.display()))?;
            return register(p, bytes).map_err(|e| format!("{FONT_ENV}={e}"));
        }
        let mut candidates: Vec<PathBuf> = FONT_PATHS.iter().map(PathBuf::from).collect();
        if let Ok(o) = std::process::Command::new("fc-match")
            .args(["-f", "%{file}", "sans-serif"])
            .output()
        {
            let p = String::from_utf8_lossy(&o.stdout).trim().to_string();
            if p.ends_with(".ttf") {
                candidates.insert(0, PathBuf::from(p));
            }
        }
        for p in candidates {
            if let Ok(bytes) = std::fs::read(&p) {
                return register(p, bytes);
            }
        }
        Err("no TrueType font found for the chart's text (install fonts-dejavu-core)".into())
    });
    r.as_ref().map(|_| ()).map_err(|e| anyhow!("{e}"))
}

/// Registers the font file `p` (its `bytes`, kept for the process) as
/// "sans-serif", regular and bold.
fn register(p: PathBuf, bytes: Vec<u8>) -> Result<PathBuf, String> {
    let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
    for style in [FontStyle::Normal, FontStyle::Bold] {
        if plotters::style::register_font("sans-serif", style, bytes).is_err() {
            return Err(format!("{}: not a usable TrueType font", p.display()));
        }
    }
    Ok(p)
}

/// A heat map: a value per (row, column), None where there is none.
#[derive(Clone, Debug, Default)]
pub struct HeatMap {
    pub title: String,
    pub rows: Vec<String>,
    pub columns: Vec<String>,
    pub row_label: String,
    pub column_label: String,
    /// values[row][column]; at least 1 where present (a ratio to the best).
    pub values: Vec<Vec<Option<f64>>>,
    pub value_label: String,
}

enum Drawing<'a> {
    Chart(&'a Chart),
    Heat(&'a HeatMap),
}

fn render_any<DB: DrawingBackend>(d: &Drawing, root: &DrawingArea<DB, Shift>) -> Result<()>
where
    DB::ErrorType: 'static,
{
    match d {
        Drawing::Chart(c) => render(c, root),
        Drawing::Heat(h) => render_heat(h, root),
    }
}

/// Draws `chart` to `path` (.svg or .png), atomically.
pub fn draw(chart: &Chart, path: &Path) -> Result<()> {
    draw_any(&Drawing::Chart(chart), path)
}

/// Draws `heat` to `path` (.svg or .png), atomically.
pub fn draw_heat_map(heat: &HeatMap, path: &Path) -> Result<()> {
    draw_any(&Drawing::Heat(heat), path)
}

fn draw_any(d: &Drawing, path: &Path) -> Result<()> {
    font()?;
    match crate::files::extension(path).as_deref() {
        Some("svg") => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
                render_any(d, &root)?;
                root.present().map_err(|e| anyhow!("{e}"))?;
            }
            crate::files::write_bytes(&crate::files::Dest::File(path.into()), svg.as_bytes())
        }
        Some("png") => {
            let mut buf = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
            {
                let root = BitMapBackend::with_buffer(&mut buf, SIZE).into_drawing_area();
                render_any(d, &root)?;
                root.present().map_err(|e| anyhow!("{e}"))?;
            }
            let img = image::RgbImage::from_raw(SIZE.0, SIZE.1, buf).context("plot buffer size")?;
            let mut bytes = Vec::new();
            img.write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::Png,
            )?;
            crate::files::write_bytes(&crate::files::Dest::File(path.into()), &bytes)
        }
        _ => bail!("{}: charts are written as .svg or .png", path.display()),
    }
}

/// The heat map: one cell per value, coloured on a log scale from the
/// smallest (light) to the largest (dark), the value written in it; row
/// names on the left, column names on top.
fn render_heat<DB: DrawingBackend>(h: &HeatMap, root: &DrawingArea<DB, Shift>) -> Result<()>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("cannot draw the heat map: {e}");
    root.fill(&WHITE).map_err(e)?;
    let (nr, nc) = (h.rows.len() as f64, h.columns.len() as f64);
    let mut c = ChartBuilder::on(root)
        .caption(&h.title, ("sans-serif", 22))
        .margin(16)
        .build_cartesian_2d(-1.0..nc, -1.0..nr + 1.0)
        .map_err(e)?;
    let vals: Vec<f64> = h.values.iter().flatten().flatten().copied().collect();
    let lo = vals
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .max(1e-12);
    let hi = vals.iter().copied().fold(0.0, f64::max).max(lo * 1.0001);
    let lut = nv_flip::magma_lut().to_vec();
    let font = ("sans-serif", 15).into_font();
    for (ri, row) in h.values.iter().enumerate() {
        // Row 0 at the top.
        let y = nr - 1.0 - ri as f64;
        for (ci, v) in row.iter().enumerate() {
            let x = ci as f64;
            let (fill, text) = match v {
                Some(v) => {
                    let t = ((v / lo).ln() / (hi / lo).ln()).clamp(0.0, 1.0);
                    // Light (best) to dark (worst) on the magma map.
                    let k = ((1.0 - t) * 200.0 + 40.0).round() as usize * 3;
                    (RGBColor(lut[k], lut[k + 1], lut[k + 2]), format!("{v:.2}"))
                }
                None => (RGBColor(220, 220, 220), "—".into()),
            };
            c.draw_series(std::iter::once(Rectangle::new(
                [(x, y), (x + 1.0, y + 1.0)],
                fill.filled(),
            )))
            .map_err(e)?;
            let ink = if v.is_some_and(|v| ((v / lo).ln() / (hi / lo).ln()) > 0.5) {
                WHITE
            } else {
                BLACK
            };
            c.draw_series(std::iter::once(Text::new(
                text,
                (x + 0.35, y + 0.6),
                font.clone().color(&ink),
            )))
            .map_err(e)?;
        }
        c.draw_series(std::iter::once(Text::new(
            h.rows[ri].clone(),
            (-0.9, y + 0.6),
            font.clone(),
        )))
        .map_err(e)?;
    }
    for (ci, name) in h.columns.iter().enumerate() {
        c.draw_series(std::iter::once(Text::new(
            name.clone(),
            (ci as f64 + 0.35, nr + 0.4),
            font.clone(),
        )))
        .map_err(e)?;
    }
    c.draw_series(std::iter::once(Text::new(
        format!(
            "{} across, {} down; cells: {}",
            h.column_label, h.row_label, h.value_label
        ),
        (-0.9, -0.5),
        font.clone(),
    )))
    .map_err(e)?;
    Ok(())
}

/// The range of `v` padded for display; on log axes strictly positive.
fn range(v: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for x in v.filter(|x| x.is_finite() && (!log || *x > 0.0)) {
        lo = lo.min(x);
        hi = hi.max(x);
    }
    if lo > hi {
        return if log { (0.1, 10.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 1.5, hi * 1.5)
    } else {
        let pad = ((hi - lo) * 0.05).max(1e-9 * hi.abs().max(1.0));
        (lo - pad, hi + pad)
    }
}

fn render<DB: DrawingBackend>(chart: &Chart, root: &DrawingArea<DB, Shift>) -> Result<()>
where
    DB::ErrorType: 'static,
{
    root.fill(&WHITE).map_err(|e| anyhow!("{e}"))?;
    let xs = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.0));
    let ys = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.1));
    let (x0, x1) = if chart.x_categories.is_empty() {
        range(xs, chart.log_x)
    } else {
        (-0.5, chart.x_categories.len() as f64 - 0.5)
    };
    let (y0, y1) = range(ys, chart.log_y);
    match (chart.log_x && chart.x_categories.is_empty(), chart.log_y) {
        (false, false) => body(chart, root, x0..x1, y0..y1),
        (true, false) => body(chart, root, (x0..x1).log_scale(), y0..y1),
        (false, true) => body(chart, root, x0..x1, (y0..y1).log_scale()),
        (true, true) => body(chart, root, (x0..x1).log_scale(), (y0..y1).log_scale()),
    }
}

fn body<DB, X, Y>(chart: &Chart, root: &DrawingArea<DB, Shift>, x: X, y: Y) -> Result<()>
where
    DB: DrawingBackend,
    DB::ErrorType: 'static,
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| anyhow!("cannot draw the chart: {e}");
    let mut c = ChartBuilder::on(root)
        .caption(&chart.title, ("sans-serif", 22))
        .margin(16)
        .x_label_area_size(48)
        .y_label_area_size(72)
        .build_cartesian_2d(x, y)
        .map_err(e)?;
    let cats = chart.x_categories.clone();
    let fmt_x = move |v: &f64| -> String {
        if cats.is_empty() {
            short(*v)
        } else {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < cats.len() {
                cats[i as usize].clone()
            } else {
                String::new()
            }
        }
    };
    let mut mesh = c.configure_mesh();
    mesh.x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .x_label_formatter(&fmt_x)
        .y_label_formatter(&|v| short(*v))
        .label_style(("sans-serif", 14));
    if !chart.x_categories.is_empty() {
        mesh.x_labels(chart.x_categories.len() * 2 + 1);
    }
    mesh.draw().map_err(e)?;
    for (i, s) in chart.series.iter().enumerate() {
        let color = match s.color {
            Some((r, g, b)) => RGBColor(r, g, b).to_rgba(),
            None => Palette99::pick(i).to_rgba(),
        };
        let style = ShapeStyle::from(&color).stroke_width(2);
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .collect();
        if s.line && pts.len() > 1 {
            c.draw_series(LineSeries::new(pts.clone(), style))
                .map_err(e)?;
        }
        c.draw_series(pts.iter().map(|&p| Circle::new(p, 4, style.filled())))
            .map_err(e)?
            .label(s.name.as_str())
            .legend(move |(x, y)| Circle::new((x + 8, y), 5, color.filled()));
        let marked: Vec<(f64, f64)> = s
            .marked
            .iter()
            .filter_map(|&k| s.points.get(k).copied())
            .collect();
        c.draw_series(marked.into_iter().map(|p| Circle::new(p, 9, style)))
            .map_err(e)?;
    }
    c.configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(e)?;
    Ok(())
}

/// A compact label: 1k, 2.5M, 0.01, 350.
fn short(v: f64) -> String {
    let a = v.abs();
    if a >= 1e9 {
        format!("{}G", trim(v / 1e9))
    } else if a >= 1e6 {
        format!("{}M", trim(v / 1e6))
    } else if a >= 1e4 {
        format!("{}k", trim(v / 1e3))
    } else {
        trim(v)
    }
}

fn trim(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// Least-squares slope of log10(y) against log10(x): the exponent k of
/// y ∝ x^k.
pub fn loglog_slope(points: &[(f64, f64)]) -> Option<f64> {
    let p: Vec<(f64, f64)> = points
        .iter()
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .map(|(x, y)| (x.log10(), y.log10()))
        .collect();
    if p.len() < 2 {
        return None;
    }
    let n = p.len() as f64;
    let mx = p.iter().map(|q| q.0).sum::<f64>() / n;
    let my = p.iter().map(|q| q.1).sum::<f64>() / n;
    let sxx: f64 = p.iter().map(|q| (q.0 - mx) * (q.0 - mx)).sum();
    let sxy: f64 = p.iter().map(|q| (q.0 - mx) * (q.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_power_law() {
        let pts: Vec<(f64, f64)> = (1..6)
            .map(|i| (10f64.powi(i), 3.0 * 10f64.powi(i).powf(0.25)))
            .collect();
        assert!((loglog_slope(&pts).unwrap() - 0.25).abs() < 1e-9);
        assert_eq!(loglog_slope(&pts[..1]), None);
    }

    #[test]
    fn labels_are_short() {
        assert_eq!(short(1000.0), "1000");
        assert_eq!(short(25000.0), "25k");
        assert_eq!(short(2_500_000.0), "2.5M");
        assert_eq!(short(0.0125), "0.013");
    }

    #[test]
    fn charts_draw_to_svg_and_png() {
        // scripts/test.sh and .ci/run install fonts-dejavu-core.
        font().expect("a TrueType font for the charts");
        let d = tempfile::tempdir().unwrap();
        let chart = Chart {
            title: "t".into(),
            x_label: "primitives".into(),
            y_label: "seconds".into(),
            log_x: true,
            log_y: true,
            series: vec![Series::new("a", vec![(1e3, 0.1), (1e6, 0.2)])],
            x_categories: vec![],
        };
        for name in ["c.svg", "c.png"] {
            let p = d.path().join(name);
            draw(&chart, &p).unwrap();
            let bytes = std::fs::read(&p).unwrap();
            assert!(bytes.len() > 1000, "{name}: {} bytes", bytes.len());
        }
        let svg = std::fs::read_to_string(d.path().join("c.svg")).unwrap();
        assert!(svg.contains("primitives") && svg.contains("<circle"));
        assert!(draw(&chart, &d.path().join("c.pdf")).is_err());
    }
}
