//! Error-against-run-time plots of an [`AccuracyReport`], as SVG and PNG.
//!
//! One series per engine and layout: the worst relative L2 error over the sample times (log y)
//! against the wall time per simulated second (log x), each point labelled with its time step
//! as a fraction of the stable bound; a grey line marks the reference's self-check error.
//!
//! Text in a PNG needs a font. fontconfig is not on every machine, so a TrueType font is looked
//! for at run time ([`find_font`]: `LANCET_FONT`, then common system paths) and registered with
//! plotters' `ab_glyph` support. Without one, the PNG is still written, without text, and the
//! caller is told so. The SVG names its text by font family and is always complete.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::accuracy::AccuracyReport;
use crate::error::{Error, Result};

/// Font family name the plots ask for.
const FAMILY: &str = "sans-serif";

/// Where the plots went.
#[derive(Debug, Clone)]
pub struct PlotFiles {
    /// The SVG plot.
    pub svg: PathBuf,
    /// The PNG plot.
    pub png: PathBuf,
    /// Why the PNG has no text, if it has none.
    pub note: Option<String>,
}

/// A TrueType font for PNG text: the file named by `LANCET_FONT` if it exists (set it to an
/// empty string for none), else the first of DejaVu Sans, Liberation Sans, Noto Sans, FreeSans
/// in their usual places, else any `.ttf` under `/usr/share/fonts`.
pub fn find_font() -> Option<PathBuf> {
    if let Some(f) = std::env::var_os("LANCET_FONT") {
        let p = PathBuf::from(f);
        return p.is_file().then_some(p);
    }
    const KNOWN: [&str; 7] = [
        "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/TTF/DejaVuSans.ttf",
        "/usr/share/fonts/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
        "/usr/share/fonts/truetype/noto/NotoSans-Regular.ttf",
        "/usr/share/fonts/truetype/freefont/FreeSans.ttf",
        "/Library/Fonts/Arial.ttf",
    ];
    if let Some(p) = KNOWN.iter().map(PathBuf::from).find(|p| p.is_file()) {
        return Some(p);
    }
    let mut found = Vec::new();
    find_ttf(Path::new("/usr/share/fonts"), 4, &mut found);
    found.sort();
    found.into_iter().next()
}

fn find_ttf(dir: &Path, depth: u32, found: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() && depth > 0 {
            find_ttf(&p, depth - 1, found);
        } else if p.extension().is_some_and(|x| x.eq_ignore_ascii_case("ttf")) {
            found.push(p);
        }
    }
}

/// Register `font` for plot text once per process; later calls keep the first font. Returns
/// why not, if it could not be used.
fn register(font: &Path) -> std::result::Result<(), String> {
    static REGISTERED: OnceLock<std::result::Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            let bytes = std::fs::read(font).map_err(|e| format!("{}: {e}", font.display()))?;
            // plotters keeps fonts for the life of the process.
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            plotters::style::register_font(FAMILY, FontStyle::Normal, bytes)
                .map_err(|_| format!("{}: not a usable TrueType font", font.display()))
        })
        .clone()
}

/// Write `accuracy.svg` and `accuracy.png` into `dir` (created if missing). `font` is the
/// TrueType file for PNG text (see [`find_font`]); with `None`, or one that cannot be read, the
/// PNG has no text and [`PlotFiles::note`] says why.
pub fn write_plots(report: &AccuracyReport, dir: &Path, font: Option<&Path>) -> Result<PlotFiles> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let svg = dir.join("accuracy.svg");
    let png = dir.join("accuracy.png");
    let registered = match font {
        Some(f) => register(f),
        None => Err("no TrueType font found (set LANCET_FONT to a .ttf file)".into()),
    };
    let plot_err = |path: &Path, e: String| Error::Unsupported(format!("{}: {e}", path.display()));
    let size = canvas(report);
    {
        let root = SVGBackend::new(&svg, size).into_drawing_area();
        // The SVG backend writes text without measuring it; the chart's own labels need the
        // font's metrics.
        draw(&root, report, registered.is_ok(), true).map_err(|e| plot_err(&svg, e))?;
        root.present().map_err(|e| plot_err(&svg, e.to_string()))?;
    }
    {
        let root = BitMapBackend::new(&png, size).into_drawing_area();
        let ok = registered.is_ok();
        draw(&root, report, ok, ok).map_err(|e| plot_err(&png, e))?;
        root.present().map_err(|e| plot_err(&png, e.to_string()))?;
    }
    Ok(PlotFiles {
        svg,
        png,
        note: registered
            .err()
            .map(|why| format!("PNG written without text: {why}")),
    })
}

/// Width of the chart's area, px; the legend takes what its text needs to the right of it.
const CHART_WIDTH: u32 = 760;

/// Left edge of the legend's text, px from the legend's left.
const LEGEND_TEXT: u32 = 48;

/// The legend's first line, and the distance between its series lines and between its notes,
/// px.
const LEGEND_TOP: i32 = 40;
const SERIES_LINE: i32 = 24;
const NOTE_LINE: i32 = 18;

/// Widths of a character of the legend's 14 px series names and 12 px notes, px: a little
/// above the common fonts' average advance (DejaVu Sans: 7.7 and 6.6), so that the longest
/// name is never cut off by the image's edge.
const SERIES_CHAR: u32 = 8;
const NOTE_CHAR: u32 = 7;

/// The legend's notes under the series: the reference's self-check, what the labels and errors
/// are, and what was asked for but not run (the reasons are printed with the table).
fn legend_notes(report: &AccuracyReport) -> Vec<String> {
    let mut notes = vec![
        "reference self-check".to_string(),
        format!(
            "(dt {:.2e} s vs {:.2e} s)",
            report.reference.check_dt, report.reference.dt
        ),
        String::new(),
        "point labels: dt / stable bound".to_string(),
        format!("bound {:.3e} s", report.dt_bound),
        "error: worst of the sample times".to_string(),
        format!(
            "t = {} s",
            report
                .sample_times
                .iter()
                .map(|t| format!("{t:.2e}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
    ];
    if !report.skipped.is_empty() {
        notes.push(String::new());
        notes.push("not run (reasons with the table):".to_string());
        // Each entry reads "<what> skipped: <why>"; the plot names what.
        notes.extend(report.skipped.iter().map(|s| {
            let what = s.split(": ").next().unwrap_or(s);
            format!("  {}", what.trim_end_matches(" skipped"))
        }));
    }
    notes
}

/// The image's size, px: the chart, and to its right a legend as wide as its longest line
/// needs; tall enough for every series and note.
fn canvas(report: &AccuracyReport) -> (u32, u32) {
    let series = report.series();
    let longest = |lines: &[String], per_char: u32| {
        lines
            .iter()
            .map(|l| l.chars().count() as u32 * per_char)
            .max()
            .unwrap_or(0)
    };
    let notes = legend_notes(report);
    let text = longest(&series, SERIES_CHAR).max(longest(&notes, NOTE_CHAR));
    let legend = (LEGEND_TEXT + text + 12).max(240);
    let bottom = LEGEND_TOP + SERIES_LINE * series.len() as i32 + NOTE_LINE * notes.len() as i32;
    (CHART_WIDTH + legend, (bottom + 30).max(640) as u32)
}

/// The fraction as a short label: `1`, `1/2`, `1/16`, or a decimal.
fn fraction_label(f: f64) -> String {
    let inv = 1.0 / f;
    if (inv - inv.round()).abs() < 1e-9 && inv.round() >= 1.0 {
        if inv.round() == 1.0 {
            "1".into()
        } else {
            format!("1/{}", inv.round())
        }
    } else {
        format!("{f}")
    }
}

/// Draw the plot. `metrics`: the font is registered, so the chart may lay out its captions and
/// axis labels. `text`: the backend can draw text at all (the legend and point labels).
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    report: &AccuracyReport,
    metrics: bool,
    text: bool,
) -> std::result::Result<(), String> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(err)?;
    let (area, legend) = root.split_horizontally(CHART_WIDTH);

    // Points: (x, y, fraction) per series, errors clamped to a floor so that a zero (the
    // reference against itself) still shows on the log axis.
    const FLOOR: f64 = 1e-16;
    let series = report.series();
    let points: Vec<Vec<(f64, f64, f64)>> = series
        .iter()
        .map(|s| {
            report
                .rows
                .iter()
                .filter(|r| &r.series == s && r.diverged.is_none())
                .map(|r| (r.wall_s_per_sim_s, r.worst_relative_l2(), r.fraction))
                .filter(|(x, y, _)| x.is_finite() && *x > 0.0 && y.is_finite())
                .map(|(x, y, f)| (x, y.max(FLOOR), f))
                .collect()
        })
        .collect();
    let self_error = report.reference_self_error();
    let all = points.iter().flatten();
    let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
    for &(x, y, _) in all {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if self_error.is_finite() && self_error > 0.0 {
        (y0, y1) = (y0.min(self_error), y1.max(self_error));
    }
    if !(x0.is_finite() && x1 > 0.0) {
        (x0, x1) = (1e-3, 1.0);
    }
    if !(y0.is_finite() && y1 > 0.0) {
        (y0, y1) = (1e-8, 1.0);
    }
    // Pad by a factor on each side so that points do not sit on the frame, then out to whole
    // decades: a log axis labels its decades, so a range inside one (a single point, or a
    // ladder whose run times differ by less than ten times) would show no tick label at all.
    let decade_below = |v: f64| 10f64.powf(v.log10().floor());
    let decade_above = |v: f64| 10f64.powf(v.log10().ceil());
    let (x0, x1) = (decade_below(x0 / 1.5), decade_above(x1 * 1.5));
    let (y0, y1) = (decade_below(y0 / 3.0), decade_above(y1 * 3.0));

    let mut builder = ChartBuilder::on(&area);
    builder.margin(15);
    if metrics {
        builder
            .caption(
                format!(
                    "{}: error against run time ({} nodes)",
                    report.scene, report.nodes
                ),
                (FAMILY, 20),
            )
            .x_label_area_size(45)
            .y_label_area_size(70);
    }
    let mut chart = builder
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    if metrics {
        chart
            .configure_mesh()
            .x_desc("wall time per simulated second (s/s)")
            .y_desc("relative L2 error, worst sample time")
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .label_style((FAMILY, 13))
            .axis_desc_style((FAMILY, 15))
            .draw()
            .map_err(err)?;
    } else {
        chart
            .plotting_area()
            .draw(&Rectangle::new(
                [(x0, y0), (x1, y1)],
                ShapeStyle::from(&BLACK).stroke_width(1),
            ))
            .map_err(err)?;
    }
    if self_error.is_finite() && self_error > 0.0 {
        chart
            .draw_series(DashedLineSeries::new(
                [(x0, self_error), (x1, self_error)],
                6,
                4,
                ShapeStyle::from(&RGBColor(120, 120, 120)).stroke_width(1),
            ))
            .map_err(err)?;
    }
    // Point labels placed clear of each other and of every marker (`labels::place_labels`):
    // 11 px text, about 6.5 px a character.
    let anchors: Vec<(i32, i32)> = points
        .iter()
        .flatten()
        .map(|&(x, y, _)| chart.backend_coord(&(x, y)))
        .collect();
    let sizes: Vec<(i32, i32)> = points
        .iter()
        .flatten()
        .map(|&(_, _, f)| (fraction_label(f).chars().count() as i32 * 13 / 2 + 2, 12))
        .collect();
    let mut offsets = super::labels::place_labels(&anchors, &sizes).into_iter();
    for (i, pts) in points.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let series_offsets: Vec<Option<(i32, i32)>> = offsets.by_ref().take(pts.len()).collect();
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|&(x, y, _)| (x, y)),
                color.stroke_width(2),
            ))
            .map_err(err)?;
        chart
            .draw_series(
                pts.iter()
                    .map(|&(x, y, _)| Circle::new((x, y), 4, color.filled())),
            )
            .map_err(err)?;
        if text {
            chart
                .draw_series(
                    pts.iter()
                        .zip(&series_offsets)
                        .filter_map(|(&(x, y, f), o)| {
                            o.map(|offset| {
                                EmptyElement::at((x, y))
                                    + Text::new(
                                        fraction_label(f),
                                        offset,
                                        (FAMILY, 11).into_font().color(&color),
                                    )
                            })
                        }),
                )
                .map_err(err)?;
        }
    }

    // The legend, drawn by hand so that the SVG has it even when no font is registered.
    let line = |i: usize| LEGEND_TOP + SERIES_LINE * i as i32;
    let text_x = LEGEND_TEXT as i32;
    for (i, s) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        legend
            .draw(&PathElement::new(
                [(10, line(i)), (40, line(i))],
                color.stroke_width(2),
            ))
            .map_err(err)?;
        legend
            .draw(&Circle::new((25, line(i)), 4, color.filled()))
            .map_err(err)?;
        if text {
            legend
                .draw(&Text::new(
                    s.clone(),
                    (text_x, line(i) - 7),
                    (FAMILY, 14).into_font(),
                ))
                .map_err(err)?;
        }
    }
    let n = series.len();
    legend
        .draw(&PathElement::new(
            [(10, line(n)), (40, line(n))],
            ShapeStyle::from(&RGBColor(120, 120, 120)).stroke_width(1),
        ))
        .map_err(err)?;
    if text {
        for (k, note) in legend_notes(report).into_iter().enumerate() {
            legend
                .draw(&Text::new(
                    note,
                    (text_x, line(n) - 7 + NOTE_LINE * k as i32),
                    (FAMILY, 12).into_font(),
                ))
                .map_err(err)?;
        }
    }
    Ok(())
}
