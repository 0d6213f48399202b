//! Line charts from tables: lines with optional bands (spread), drawn with `plotters` into an
//! RGB buffer (no system font or image library: the font is DejaVu Sans, bundled by a crate).

use crate::draw::render::Image;
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::sync::Once;

/// One line of a chart, with an optional band (x, low, high) drawn behind it.
#[derive(Clone, Debug, Default)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub band: Vec<(f64, f64, f64)>,
    /// Colour slot (series with the same slot share a colour).
    pub color: usize,
    pub dashed: bool,
}

/// A chart: title, axis labels, series.
#[derive(Clone, Debug, Default)]
pub struct Chart {
    pub title: String,
    pub xlabel: String,
    pub ylabel: String,
    pub series: Vec<Series>,
}

const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, dejavu::sans::regular())
            .map_err(|_| ())
            .expect("bundled DejaVu Sans is a valid font");
    });
}

/// A tick label: six significant digits at most, without trailing zeros (`0.12`, not
/// `0.12000000000000001`), in exponent form beyond 1e5 or below 1e-3.
fn tick(x: f64) -> String {
    let trim = |s: String| {
        if s.contains('.') {
            s.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            s
        }
    };
    let a = x.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        let s = format!("{x:.3e}");
        match s.split_once('e') {
            Some((m, e)) => format!("{}e{e}", trim(m.to_string())),
            None => s,
        }
    } else {
        let decimals = (5 - a.log10().floor() as i32).clamp(0, 8) as usize;
        trim(format!("{x:.decimals$}"))
    }
}

/// A tick at `x` on an axis `span` long: zero where the axis' arithmetic left only round-off
/// (a tick at -6.9e-18 is the tick at 0).
fn snap(x: f64, span: f64) -> f64 {
    if x.abs() <= 1e-9 * span.abs() {
        0.0
    } else {
        x
    }
}

/// Pictures of one height side by side, left to right, as one picture.
pub fn side_by_side(images: &[Image]) -> Image {
    let height = images.iter().map(|i| i.height).max().unwrap_or(0);
    let width: u32 = images.iter().map(|i| i.width).sum();
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    let mut left = 0;
    for img in images {
        for y in 0..img.height {
            let from = (y * img.width * 3) as usize;
            let to = ((y * width + left) * 3) as usize;
            let row = (img.width * 3) as usize;
            rgb[to..to + row].copy_from_slice(&img.rgb[from..from + row]);
        }
        left += img.width;
    }
    Image { width, height, rgb }
}

/// Draws the chart into a `width` x `height` picture.
pub fn draw(chart: &Chart, width: u32, height: u32) -> Result<Image, String> {
    register_font();
    let mut buf = vec![255u8; (width * height * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        // Only finite points are drawn and set the axes: a point with a coordinate that is not
        // finite has no place on them, and its other coordinate, left out of the ranges, would
        // map far outside the picture (an overflow in plotters' pixel arithmetic).
        let finite = |x: f64, lo: f64, hi: f64| x.is_finite() && lo.is_finite() && hi.is_finite();
        let drawn: Vec<Drawn> = chart
            .series
            .iter()
            .map(|s| {
                let points = s.points.iter().copied();
                let band = s.band.iter().copied();
                (
                    points.filter(|&(x, y)| finite(x, y, y)).collect(),
                    band.filter(|&(x, lo, hi)| finite(x, lo, hi)).collect(),
                )
            })
            .collect();
        let all = drawn.iter().flat_map(|(points, band)| {
            points
                .iter()
                .map(|&(x, y)| (x, y, y))
                .chain(band.iter().copied())
        });
        let (mut x0, mut x1, mut y0, mut y1) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        );
        for (x, lo, hi) in all {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(lo);
            y1 = y1.max(hi);
        }
        if !x0.is_finite() {
            return Err("nothing to plot: no finite points".into());
        }
        // A margin of the range, at least a millionth of the values' size (a single value of
        // 1e300 padded by 1e-9 would leave an axis of no width in floating point).
        let pad = |lo: f64, hi: f64, share: f64| {
            ((hi - lo) * share)
                .max(1e-6 * lo.abs().max(hi.abs()))
                .max(1e-9)
        };
        let (padx, pady) = (pad(x0, x1, 0.04), pad(y0, y1, 0.08));
        // The axes' ends and their ticks need the padded range in floating point.
        let ends = [x0 - padx, x1 + padx, y0 - pady, y1 + pady];
        if !(ends.iter().all(|e| e.is_finite())
            && (ends[1] - ends[0]).is_finite()
            && (ends[3] - ends[2]).is_finite())
        {
            return Err(format!(
                "the values span more than a float can hold (x from {x0:e} to {x1:e}, y from {y0:e} to {y1:e})"
            ));
        }
        let mut ctx = ChartBuilder::on(&root)
            .caption(&chart.title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(64)
            .build_cartesian_2d((x0 - padx)..(x1 + padx), (y0 - pady)..(y1 + pady))
            .map_err(|e| e.to_string())?;
        let integer_x = chart
            .series
            .iter()
            .all(|s| s.points.iter().all(|p| p.0.fract() == 0.0));
        let fmt_x = move |x: &f64| {
            if integer_x {
                // Whole-number data (levels, counts): only whole ticks are labelled.
                if x.fract() == 0.0 {
                    format!("{x:.0}")
                } else {
                    String::new()
                }
            } else {
                tick(snap(*x, x1 - x0 + 2.0 * padx))
            }
        };
        let fmt_y = |y: &f64| tick(snap(*y, y1 - y0 + 2.0 * pady));
        ctx.configure_mesh()
            .x_label_formatter(&fmt_x)
            .y_label_formatter(&fmt_y)
            .x_desc(&chart.xlabel)
            .y_desc(&chart.ylabel)
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| e.to_string())?;
        for (s, (_, band)) in chart.series.iter().zip(&drawn) {
            let c = COLORS[s.color % COLORS.len()];
            if band.len() > 1 {
                let mut poly: Vec<(f64, f64)> = band.iter().map(|&(x, lo, _)| (x, lo)).collect();
                poly.extend(band.iter().rev().map(|&(x, _, hi)| (x, hi)));
                ctx.draw_series(std::iter::once(Polygon::new(
                    poly,
                    c.mix(if s.dashed { 0.08 } else { 0.16 }),
                )))
                .map_err(|e| e.to_string())?;
            }
        }
        for (s, (points, _)) in chart.series.iter().zip(&drawn) {
            let c = COLORS[s.color % COLORS.len()];
            let style = c.stroke_width(2);
            let line = if s.dashed {
                ctx.draw_series(DashedLineSeries::new(points.clone(), 8, 5, style))
            } else {
                ctx.draw_series(LineSeries::new(points.clone(), style))
            }
            .map_err(|e| e.to_string())?;
            let dashed = s.dashed;
            line.label(&s.label).legend(move |(x, y)| {
                // Coordinates after EmptyElement::at are relative to (x, y).
                let (a, b) = if dashed {
                    ((0, 7), (11, 18))
                } else {
                    ((0, 9), (9, 18))
                };
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(a.0, 0), (a.1, 0)], c.stroke_width(2))
                    + PathElement::new(vec![(b.0, 0), (b.1, 0)], c.stroke_width(2))
            });
            ctx.draw_series(points.iter().map(|&p| Circle::new(p, 3, c.filled())))
                .map_err(|e| e.to_string())?;
        }
        // A legend only where a series has a name to show.
        if chart.series.iter().any(|s| !s.label.is_empty()) {
            ctx.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK.mix(0.3))
                .label_font(("sans-serif", 13))
                .position(legend_corner(
                    &drawn,
                    [x0 - padx, x1 + padx, y0 - pady, y1 + pady],
                ))
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    Ok(Image {
        width,
        height,
        rgb: buf,
    })
}

/// A series' finite points and band, as drawn.
type Drawn = (Vec<(f64, f64)>, Vec<(f64, f64, f64)>);

/// The corner of the plot whose quarter-width, quarter-height box holds the fewest points (the
/// legend's place, so that it hides the least data); lower right among equals.
fn legend_corner(drawn: &[Drawn], [x0, x1, y0, y1]: [f64; 4]) -> SeriesLabelPosition {
    let (wx, wy) = (0.35 * (x1 - x0), 0.3 * (y1 - y0));
    let corners = [
        (SeriesLabelPosition::LowerRight, x1 - wx, x1, y0, y0 + wy),
        (SeriesLabelPosition::UpperRight, x1 - wx, x1, y1 - wy, y1),
        (SeriesLabelPosition::LowerLeft, x0, x0 + wx, y0, y0 + wy),
        (SeriesLabelPosition::UpperLeft, x0, x0 + wx, y1 - wy, y1),
    ];
    let inside = |&(_, a, b, c, d): &(SeriesLabelPosition, f64, f64, f64, f64)| {
        let points = drawn.iter().flat_map(|(p, _)| p.iter());
        points
            .filter(|&&(x, y)| x >= a && x <= b && y >= c && y <= d)
            .count()
    };
    // The first of equals: lower right.
    let (corner, ..) = corners
        .iter()
        .min_by_key(|c| inside(c))
        .expect("four corners");
    corner.clone()
}

/// Summary statistics of one group of values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stats {
    pub n: usize,
    pub mean: f64,
    pub std: f64,
    pub min: f64,
    pub max: f64,
    pub p05: f64,
    pub p95: f64,
}

impl Stats {
    /// Statistics of `values` (sample standard deviation; 0 for one value). `None` if empty.
    pub fn of(values: &[f64]) -> Option<Stats> {
        if values.is_empty() {
            return None;
        }
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let var = if n > 1 {
            v.iter().map(|x| crate::math::square(x - mean)).sum::<f64>() / (n - 1) as f64
        } else {
            0.0
        };
        let q = |p: f64| v[((n - 1) as f64 * p).round() as usize];
        Some(Stats {
            n,
            mean,
            std: var.sqrt(),
            min: v[0],
            max: v[n - 1],
            p05: q(0.05),
            p95: q(0.95),
        })
    }
}

/// Groups `(series key, x, y)` rows and returns, per series key (sorted) and x (sorted), the
/// statistics of y. Rows with x or y not finite are left out, as they are of the picture (a
/// seed whose value is undefined drops out of its group's mean; `n` counts those kept).
pub fn group_stats(rows: &[(String, f64, f64)]) -> BTreeMap<String, Vec<(f64, Stats)>> {
    let mut groups: BTreeMap<String, BTreeMap<u64, (f64, Vec<f64>)>> = BTreeMap::new();
    for (key, x, y) in rows {
        if !(x.is_finite() && y.is_finite()) {
            continue;
        }
        // Order x by its value: map f64 to a monotone integer key.
        let bits = x.to_bits();
        let ord = if bits >> 63 == 1 {
            !bits
        } else {
            bits | (1 << 63)
        };
        groups
            .entry(key.clone())
            .or_default()
            .entry(ord)
            .or_insert((*x, Vec::new()))
            .1
            .push(*y);
    }
    groups
        .into_iter()
        .map(|(k, xs)| {
            (
                k,
                xs.into_values()
                    .filter_map(|(x, ys)| Stats::of(&ys).map(|s| (x, s)))
                    .collect(),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_that_are_not_finite_stay_out_of_the_statistics() {
        let row = |x: f64, y: f64| ("g".to_string(), x, y);
        let rows = [
            row(1.0, f64::NAN),
            row(1.0, 4.0),
            row(1.0, 2.0),
            row(1.0, f64::INFINITY),
            row(2.0, f64::NAN),
            row(f64::NAN, 5.0),
        ];
        let g = &group_stats(&rows)["g"];
        assert_eq!(
            g.len(),
            1,
            "x = 2 holds no finite value, x = NaN is no place: {g:?}"
        );
        let (x, s) = g[0];
        assert_eq!(x, 1.0);
        assert_eq!((s.n, s.mean, s.min, s.max), (2, 3.0, 2.0, 4.0));
        assert!(s.std.is_finite() && s.p05.is_finite() && s.p95.is_finite());
    }

    #[test]
    fn a_tick_of_round_off_reads_zero_and_a_small_axis_keeps_its_ticks() {
        assert_eq!(tick(snap(-6.938893903907228e-18, 0.06)), "0");
        assert_eq!(tick(snap(2e-12, 1e-10)), "2e-12");
        assert_eq!(tick(snap(0.02, 0.06)), "0.02");
    }

    #[test]
    fn stats_of_known_values() {
        let s = Stats::of(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!((s.n, s.mean, s.min, s.max), (4, 2.5, 1.0, 4.0));
        assert!((s.std - (5.0f64 / 3.0).sqrt()).abs() < 1e-15);
        assert!(Stats::of(&[]).is_none());
    }

    #[test]
    fn groups_are_sorted_by_key_and_x() {
        let rows = vec![
            ("b".into(), 2.0, 1.0),
            ("a".into(), 10.0, 5.0),
            ("a".into(), -1.0, 3.0),
            ("a".into(), 10.0, 7.0),
        ];
        let g = group_stats(&rows);
        let a = &g["a"];
        assert_eq!(a.len(), 2);
        assert_eq!(a[0].0, -1.0);
        assert_eq!(a[1].1.mean, 6.0);
        assert_eq!(g.keys().collect::<Vec<_>>(), ["a", "b"]);
    }

    #[test]
    fn the_legend_goes_to_the_emptiest_corner() {
        let falling: Vec<(f64, f64)> = (0..=10).map(|i| (i as f64, -(i as f64))).collect();
        let drawn = vec![(falling, Vec::new())];
        let ends = [0.0, 10.0, -10.0, 0.0];
        // A line from upper left to lower right leaves the other two corners empty.
        let corner = legend_corner(&drawn, ends);
        assert!(
            matches!(
                corner,
                SeriesLabelPosition::UpperRight | SeriesLabelPosition::LowerLeft
            ),
            "{corner:?}"
        );
        let rising: Vec<(f64, f64)> = (0..=10).map(|i| (i as f64, i as f64 - 10.0)).collect();
        let corner = legend_corner(&[(rising, Vec::new())], ends);
        assert_eq!(corner, SeriesLabelPosition::LowerRight);
    }

    /// A chart of one series.
    fn chart_of(points: Vec<(f64, f64)>, band: Vec<(f64, f64, f64)>) -> Chart {
        Chart {
            title: "t".into(),
            xlabel: "x".into(),
            ylabel: "y".into(),
            series: vec![Series {
                label: "s".into(),
                points,
                band,
                ..Default::default()
            }],
        }
    }

    #[test]
    fn a_point_that_is_not_finite_is_left_out() {
        let chart = chart_of(
            vec![
                (0.0, 0.0),
                (1e308, f64::NAN),
                (1.0, 1.0),
                (f64::INFINITY, 0.5),
            ],
            vec![(0.0, -1.0, 1.0), (-1e308, f64::NAN, 0.0), (1.0, 0.0, 2.0)],
        );
        let img = draw(&chart, 160, 120).unwrap();
        assert!(img.rgb.iter().any(|&v| v < 128), "nothing drawn");
    }

    #[test]
    fn a_chart_draws() {
        let chart = chart_of(
            vec![(0.0, 1.0), (1.0, 2.0)],
            vec![(0.0, 0.5, 1.5), (1.0, 1.5, 2.5)],
        );
        let img = draw(&chart, 300, 200).unwrap();
        assert!(img.rgb.iter().any(|&v| v != 255));
        assert!(draw(&Chart::default(), 300, 200).is_err());
    }
}
