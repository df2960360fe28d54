//! The log-log plots of a `converge` run, drawn with plotters into a buffer and written as a
//! PNG beside the results. The font (DejaVu Sans Mono, under its own free license in
//! `assets/fonts/`) is built into the binary, so plots need nothing from the system.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};

use super::summary::Table;

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSansMono.ttf");

pub(crate) fn font() {
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

/// The longest legend line, in characters, before a label is wrapped.
const LABEL_CHARS: usize = 48;

/// `label` in lines of at most `max` characters, broken after a `:` or at a space (a single
/// longer word stays whole); the lines joined give the label back.
fn wrap(label: &str, max: usize) -> Vec<String> {
    let (mut lines, mut line) = (Vec::new(), String::new());
    // Words with the separator they end in (`:` kept, a space kept).
    for word in label.split_inclusive([':', ' ']) {
        if !line.is_empty() && line.chars().count() + word.trim_end().chars().count() > max {
            lines.push(std::mem::take(&mut line));
        }
        line.push_str(word);
    }
    lines.push(line);
    lines
}

/// An x axis label on a log scale: only at 1, 2 and 5 times a power of ten (the others crowd).
pub(crate) fn round_label(v: f64) -> String {
    let exponent = v.log10().floor();
    let lead = v / 10f64.powf(exponent);
    if ![1.0, 2.0, 5.0].iter().any(|d| (lead - d).abs() < 1e-6) {
        return String::new();
    }
    // As many decimals as the power of ten needs, none from 1 up.
    format!("{v:.*}", (-exponent).max(0.0) as usize)
}

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
    // A log axis holds only finite positive values: an infinite one made plotters' range loop
    // for ever.
    let shown = |&(x, y): &(f64, f64)| x > 0.0 && y > 0.0 && x.is_finite() && y.is_finite();
    let all: Vec<(f64, f64)> = table
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| (x_of(p), p.rmse.mean)))
        .filter(shown)
        .collect();
    if all.is_empty() {
        return Err("nothing to plot: no rows with positive values".into());
    }
    let (xmin, xmax) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (ymin, ymax) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    // Long labels (an atrous filter with all its settings) wrapped; about 9 pixels a character
    // at the legend's size, after the 38-pixel swatch.
    let labels: Vec<Vec<String>> = table.series.iter().map(|s| wrap(&s.label(), LABEL_CHARS)).collect();
    let longest = labels.iter().flatten().map(|l| l.chars().count()).max().unwrap_or(0) as u32;
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
            .x_label_formatter(&|v| round_label(*v))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        for (i, s) in table.series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f64)> =
                s.points.iter().map(|p| (x_of(p), p.rmse.mean)).filter(shown).collect();
            chart.draw_series(LineSeries::new(pts.clone(), color.stroke_width(2))).map_err(e)?;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled()))).map_err(e)?;
            let y = 50 + 20 * i as i32 + 16 * labels[..i].iter().map(|l| l.len() as i32 - 1).sum::<i32>();
            legend.draw(&PathElement::new(vec![(4, y), (30, y)], color.stroke_width(2))).map_err(e)?;
            for (j, line) in labels[i].iter().enumerate() {
                legend
                    .draw(&Text::new(line.as_str(), (38, y - 8 + 16 * j as i32), ("sans-serif", 14)))
                    .map_err(e)?;
            }
        }
        root.present().map_err(e)?;
    }
    crate::film::write_rgb8(path, width, HEIGHT, buf).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_labels_wrap_at_their_separators_and_lose_nothing() {
        let label =
            "atrous:passes=4:sigma_l=6:sigma_n=32:sigma_z=2:taps=3:direct_sigma_l=1.5 components edge-aware";
        let lines = wrap(label, 24);
        assert!(lines.len() > 3, "{lines:?}");
        assert_eq!(lines.concat(), label);
        for line in &lines {
            assert!(line.trim_end().chars().count() <= 24, "{line:?}");
        }
        // Short labels, and a single word longer than the limit, stay on one line.
        assert_eq!(wrap("box5 indirect", 24), vec!["box5 indirect".to_string()]);
        assert_eq!(wrap("unfiltered", 4), vec!["unfiltered".to_string()]);
    }

    #[test]
    fn log_axis_labels_only_at_one_two_and_five() {
        let shown: Vec<String> = [0.05, 0.06, 0.2, 0.3, 1.0, 4.0, 5.0, 20.0, 70.0, 500.0]
            .iter()
            .map(|&v| round_label(v))
            .collect();
        assert_eq!(shown, ["0.05", "", "0.2", "", "1", "", "5", "20", "", "500"]);
    }
}
