//! The log-log plots of a `converge` run, drawn with plotters into a buffer and written as a
//! PNG beside the results. The font (DejaVu Sans Mono, under its own free license in
//! `assets/fonts/`) is built into the binary, so plots need nothing from the system.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use super::summary::Table;

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");

fn font() {
    static REGISTER: Once = Once::new();
    REGISTER.call_once(|| {
        // The font is compiled in; if plotters rejected it the labels would be missing, not the plot.
        let _ = register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// The chart's width; the legend's column, right of it so that it never covers a line, is as
/// wide as its longest label needs (at least [`LEGEND`]).
const CHART: u32 = 880;
const LEGEND: u32 = 300;
const HEIGHT: u32 = 600;

/// RMSE against spp (or against seconds of render and filter time, with `by_time`), log-log,
/// one line per setting.
pub fn error_plot(table: &Table, by_time: bool, path: &Path) -> Result<(), String> {
    font();
    let x_of = |p: &super::summary::Point| {
        if by_time {
            p.render_seconds.mean + p.filter_seconds.mean
        } else {
            p.spp as f64
        }
    };
    let all: Vec<(f64, f64)> = table
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| (x_of(p), p.rmse.mean)))
        .filter(|(x, y)| *x > 0.0 && *y > 0.0)
        .collect();
    if all.is_empty() {
        return Err("nothing to plot: no rows with positive values".into());
    }
    let (xmin, xmax) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (ymin, ymax) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    // About 9 pixels a character at the legend's size, after the 38-pixel swatch.
    let longest = table.series.iter().map(|s| s.label().chars().count()).max().unwrap_or(0) as u32;
    let width = CHART + (48 + 9 * longest).max(LEGEND);
    let mut buf = vec![0u8; (width * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (width, HEIGHT)).into_drawing_area();
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        root.fill(&WHITE).map_err(e)?;
        let (plot, legend) = root.split_horizontally(CHART);
        let title =
            if by_time { "RMSE against render + filter time" } else { "RMSE against samples per pixel" };
        let mut chart = ChartBuilder::on(&plot)
            .caption(title, ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(80)
            .build_cartesian_2d((xmin * 0.8..xmax * 1.25).log_scale(), (ymin * 0.8..ymax * 1.25).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(if by_time { "seconds" } else { "samples per pixel" })
            .y_desc("RMSE")
            .y_labels(6)
            .y_label_formatter(&|v| format!("{v:.2e}"))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        for (i, s) in table.series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f64)> = s.points.iter().map(|p| (x_of(p), p.rmse.mean)).collect();
            chart.draw_series(LineSeries::new(pts.clone(), color.stroke_width(2))).map_err(e)?;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled()))).map_err(e)?;
            let y = 50 + 20 * i as i32;
            legend.draw(&PathElement::new(vec![(4, y), (30, y)], color.stroke_width(2))).map_err(e)?;
            legend.draw(&Text::new(s.label(), (38, y - 8), ("sans-serif", 14))).map_err(e)?;
        }
        root.present().map_err(e)?;
    }
    crate::film::write_rgb8(path, width, HEIGHT, buf).map_err(|e| e.to_string())
}
