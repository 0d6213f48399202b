//! plot: a line chart (PNG) from a CSV table, optionally of group statistics.

use anyhow::{bail, Context};
use clap::Parser;
use shared::cli;
use shared::draw::plot::{self, Chart, Series};
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  roundness < t.csv ... | plot --x k --y s3d --series level > s3d.png
  plot --x k --y s3d --series level,cap --stats --band std --stats-out stats.csv < all.csv > fig7.png
  plot --x level --y e50,poisson --ylabel \"E50 (Pa)\" --ylabel \"Poisson's ratio\" < t.csv > fig11.png
      (two panels, each with its label: a label is written as it is, commas included)

Without --stats every row is a point and rows of one series are joined in file order. With
--stats rows are grouped by series and x, and the mean is drawn with a band (--band std: mean
+- one standard deviation; minmax; p05-p95; none). With two series columns, colour follows the
first and the second column's later values are dashed.

Errors: a missing column, a row of another width or a value that is not a number stops with
the row named and exit 1, no picture written. nan and inf are numbers, left out of the picture
and of --stats; values spread wider than a float spans (1e308 and -1e308 on one axis) are
refused. Limits and errors: docs/formats/plot-csv.md.";

/// Draws a line chart from a CSV table with a header (standard input) as PNG (standard output).
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Column for the x axis
    #[arg(long)]
    x: String,
    /// Column for the y axis; several, comma-separated, draw one panel each, side by side
    #[arg(long, value_delimiter = ',', required = true)]
    y: Vec<String>,
    /// Columns (comma-separated) whose values name the series
    #[arg(long, value_delimiter = ',')]
    series: Vec<String>,
    /// Plot the mean per (series, x) with a band
    #[arg(long)]
    stats: bool,
    /// Band around the mean with --stats: std, minmax, p05-p95, none
    #[arg(long, default_value = "std")]
    band: String,
    /// With --stats, also write the group statistics as CSV to this file
    #[arg(long)]
    stats_out: Option<std::path::PathBuf>,
    #[arg(long, default_value = "")]
    title: String,
    /// The x axis's label [default: the column's name]
    #[arg(long)]
    xlabel: Option<String>,
    /// A y axis's label, as written (commas included) [default: the column's name]; give it
    /// once per --y column, in their order, for several panels
    #[arg(long)]
    ylabel: Vec<String>,
    /// Picture size WIDTHxHEIGHT
    #[arg(long, default_value = "900x600")]
    size: String,
}

fn main() -> ExitCode {
    cli::run("plot", || run(Cli::parse()))
}

fn run(args: Cli) -> anyhow::Result<()> {
    let (w, h) = args
        .size
        .split_once('x')
        .and_then(|(w, h)| Some((w.parse::<u32>().ok()?, h.parse::<u32>().ok()?)))
        .filter(|&(w, h)| (64..=8192).contains(&w) && (64..=8192).contains(&h))
        .with_context(|| {
            format!(
                "--size '{}' is not WIDTHxHEIGHT between 64 and 8192",
                args.size
            )
        })?;
    if !["std", "minmax", "p05-p95", "none"].contains(&args.band.as_str()) {
        return Err(cli::usage(format!(
            "--band '{}' is not one of std, minmax, p05-p95, none",
            args.band
        )));
    }
    let mut rdr = csv::Reader::from_reader(cli::stdin());
    let header = rdr.headers().context("reading the CSV header")?.clone();
    let col = |name: &str| {
        header.iter().position(|c| c == name).with_context(|| {
            format!(
                "no column '{name}' in the header ({})",
                header.iter().collect::<Vec<_>>().join(",")
            )
        })
    };
    let xi = col(&args.x)?;
    let yis: Vec<usize> = args
        .y
        .iter()
        .map(|y| col(y))
        .collect::<anyhow::Result<_>>()?;
    if !args.ylabel.is_empty() && args.ylabel.len() != args.y.len() {
        return Err(cli::usage(format!(
            "--ylabel is given {} times for {} y columns (once per column, or not at all)",
            args.ylabel.len(),
            args.y.len()
        )));
    }
    let si: Vec<usize> = args
        .series
        .iter()
        .map(|s| col(s))
        .collect::<anyhow::Result<_>>()?;
    let mut table: Vec<(Vec<String>, f64, Vec<f64>)> = Vec::new();
    for (n, rec) in rdr.records().enumerate() {
        let rec = rec.with_context(|| format!("CSV row {}", n + 2))?;
        let num = |i: usize| -> anyhow::Result<f64> {
            let s = rec.get(i).unwrap_or("");
            s.parse::<f64>().with_context(|| {
                format!(
                    "row {}: '{s}' in column '{}' is not a number",
                    n + 2,
                    &header[i]
                )
            })
        };
        let key = si
            .iter()
            .map(|&i| rec.get(i).unwrap_or("").to_string())
            .collect();
        let ys = yis.iter().map(|&i| num(i)).collect::<anyhow::Result<_>>()?;
        table.push((key, num(xi)?, ys));
    }
    if table.is_empty() {
        bail!("the table has no rows");
    }
    let mut panels = Vec::new();
    for (j, y) in args.y.iter().enumerate() {
        let rows: Vec<(Vec<String>, f64, f64)> = table
            .iter()
            .map(|(k, x, ys)| (k.clone(), *x, ys[j]))
            .collect();
        let ylabel = args.ylabel.get(j).cloned().unwrap_or_else(|| y.clone());
        // The statistics of the first panel only go to --stats-out.
        let stats_out = if j == 0 {
            args.stats_out.as_ref()
        } else {
            None
        };
        let chart = chart_of(&args, &rows, ylabel, stats_out)?;
        let width = w / args.y.len() as u32;
        panels.push(
            plot::draw(&chart, width, h).map_err(|e| anyhow::anyhow!("drawing the chart: {e}"))?,
        );
    }
    cli::write_png_stdout(&plot::side_by_side(&panels))
}

/// The chart of `rows` (series key, x, y): every row a point, or with `--stats` the mean per
/// (series, x) with a band; the statistics also to `stats_out`.
fn chart_of(
    args: &Cli,
    rows: &[(Vec<String>, f64, f64)],
    ylabel: String,
    stats_out: Option<&std::path::PathBuf>,
) -> anyhow::Result<Chart> {
    // Distinct values per series column, in order of appearance: colour by the first, dash by the second.
    let mut first_vals: Vec<String> = Vec::new();
    let mut second_vals: Vec<String> = Vec::new();
    for (k, _, _) in rows {
        if let Some(v) = k.first() {
            if !first_vals.contains(v) {
                first_vals.push(v.clone());
            }
        }
        if let Some(v) = k.get(1) {
            if !second_vals.contains(v) {
                second_vals.push(v.clone());
            }
        }
    }
    let label = |k: &[String]| {
        args.series
            .iter()
            .zip(k)
            .map(|(c, v)| format!("{c}={v}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let style = |k: &[String]| {
        let color = k
            .first()
            .and_then(|v| first_vals.iter().position(|x| x == v))
            .unwrap_or(0);
        let dashed = k
            .get(1)
            .is_some_and(|v| second_vals.iter().position(|x| x == v).unwrap_or(0) > 0);
        (color, dashed)
    };
    let mut series: Vec<Series> = Vec::new();
    if args.stats {
        let keyed: Vec<(String, f64, f64)> = rows
            .iter()
            .map(|(k, x, y)| (k.join("\u{1f}"), *x, *y))
            .collect();
        let groups = plot::group_stats(&keyed);
        let mut stats_csv = match stats_out {
            Some(p) => {
                let mut wtr = csv::Writer::from_path(p)
                    .with_context(|| format!("creating {}", p.display()))?;
                let mut head: Vec<String> = args.series.clone();
                head.extend([
                    args.x.clone(),
                    "n".into(),
                    "mean".into(),
                    "std".into(),
                    "min".into(),
                    "max".into(),
                    "p05".into(),
                    "p95".into(),
                ]);
                wtr.write_record(&head)?;
                Some(wtr)
            }
            None => None,
        };
        // Keep series in order of first appearance of their key.
        let mut order: Vec<String> = Vec::new();
        for (k, _, _) in &keyed {
            if !order.contains(k) {
                order.push(k.clone());
            }
        }
        for key in order {
            let parts: Vec<String> = if args.series.is_empty() {
                vec![]
            } else {
                key.split('\u{1f}').map(String::from).collect()
            };
            let pts = &groups[&key];
            let (color, dashed) = style(&parts);
            let band = pts
                .iter()
                .filter_map(|(x, s)| match args.band.as_str() {
                    "std" => Some((*x, s.mean - s.std, s.mean + s.std)),
                    "minmax" => Some((*x, s.min, s.max)),
                    "p05-p95" => Some((*x, s.p05, s.p95)),
                    _ => None,
                })
                .collect();
            if let Some(wtr) = stats_csv.as_mut() {
                for (x, s) in pts {
                    let mut rec = parts.clone();
                    rec.extend(
                        [
                            x,
                            &(s.n as f64),
                            &s.mean,
                            &s.std,
                            &s.min,
                            &s.max,
                            &s.p05,
                            &s.p95,
                        ]
                        .map(|v| v.to_string()),
                    );
                    wtr.write_record(&rec)?;
                }
            }
            series.push(Series {
                label: label(&parts),
                points: pts.iter().map(|(x, s)| (*x, s.mean)).collect(),
                band,
                color,
                dashed,
            });
        }
        if let Some(mut wtr) = stats_csv {
            wtr.flush()?;
        }
    } else {
        for (k, x, y) in rows {
            let name = label(k);
            match series.iter_mut().find(|s| s.label == name) {
                Some(s) => s.points.push((*x, *y)),
                None => {
                    let (color, dashed) = style(k);
                    series.push(Series {
                        label: name,
                        points: vec![(*x, *y)],
                        color,
                        dashed,
                        ..Default::default()
                    })
                }
            }
        }
    }
    Ok(Chart {
        title: args.title.clone(),
        xlabel: args.xlabel.clone().unwrap_or_else(|| args.x.clone()),
        ylabel,
        series,
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_well_formed() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
