//! The scaling plot of `bench-accel --plot`: millions of rays per second on one thread against
//! the scene's triangle count, log-log, one line per backend and ray kind.

use std::path::Path;

use plotters::element::DashedPathElement;
use plotters::prelude::*;

use super::rays::RayKind;
use super::BenchAccelReport;
use crate::accel::Backend;
use crate::converge::plot::{font, round_label};

const WIDTH: u32 = 900;
const HEIGHT: u32 = 560;

/// One line: a backend's Mrays/s for one ray kind, by triangle count.
type Series = (Backend, RayKind, Vec<(f64, f64)>);

/// Draws the one-thread rows of `reports` (one per scene) into the PNG at `path`.
pub fn scaling_plot(reports: &[BenchAccelReport], path: &Path) -> Result<(), String> {
    font();
    let series: Vec<Series> = [Backend::Embree, Backend::Bvh]
        .into_iter()
        .flat_map(|backend| RayKind::ALL.into_iter().map(move |kind| (backend, kind)))
        .map(|(backend, kind)| {
            let mut points: Vec<(f64, f64)> = reports
                .iter()
                .flat_map(|r| {
                    r.rows
                        .iter()
                        .filter(|row| row.backend == backend && row.rays == kind && row.threads == 1)
                        .map(|row| (r.triangles as f64, row.mrays_per_second))
                })
                .filter(|&(x, y)| x > 0.0 && y > 0.0)
                .collect();
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            (backend, kind, points)
        })
        .collect();
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.2.iter().copied()).collect();
    if all.is_empty() {
        return Err("nothing to plot: no scene with triangles and rays".into());
    }
    let (xmin, xmax) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (ymin, ymax) = all.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let mut buf = vec![0u8; (WIDTH * HEIGHT * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (WIDTH, HEIGHT)).into_drawing_area();
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        root.fill(&WHITE).map_err(e)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("Rays per second on one thread against scene size", ("sans-serif", 22))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d((xmin * 0.7..xmax * 1.4).log_scale(), (ymin * 0.7..ymax * 1.4).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("triangles")
            .y_desc("Mrays/s")
            .x_label_formatter(&|v| round_label(*v))
            .y_label_formatter(&|v| format!("{v:.1}"))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        for (backend, kind, points) in &series {
            // A colour per ray kind; Embree solid with circles, the BVH dashed with squares.
            let color = Palette99::pick(match kind {
                RayKind::Primary => 0,
                RayKind::Shadow => 1,
                RayKind::Incoherent => 2,
            })
            .to_rgba();
            let label = format!("{backend} {}", kind.name());
            match backend {
                Backend::Embree => {
                    chart
                        .draw_series(LineSeries::new(points.clone(), color.stroke_width(2)))
                        .map_err(e)?
                        .label(label)
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(2))
                        });
                    chart
                        .draw_series(points.iter().map(|&p| Circle::new(p, 4, color.filled())))
                        .map_err(e)?;
                }
                Backend::Bvh => {
                    chart
                        .draw_series(DashedLineSeries::new(points.clone(), 8, 5, color.stroke_width(2)))
                        .map_err(e)?
                        .label(label)
                        .legend(move |(x, y)| {
                            DashedPathElement::new(vec![(x, y), (x + 24, y)], 6, 3, color.stroke_width(2))
                        });
                    chart
                        .draw_series(points.iter().map(|&(x, y)| {
                            EmptyElement::at((x, y)) + Rectangle::new([(-4, -4), (4, 4)], color.filled())
                        }))
                        .map_err(e)?;
                }
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
    }
    crate::film::write_rgb8(path, WIDTH, HEIGHT, buf).map_err(|e| e.to_string())
}
