//! The summary of a `converge` run: means and spreads over seeds, and the equal-quality
//! column — how many samples (and seconds) the unfiltered render needs to reach a filtered
//! setting's error, read off the unfiltered log-log curve.

use std::fmt::Write as _;

use super::{Choice, Row};
use crate::render::sampler::SamplerKind;

/// Mean and sample standard deviation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stat {
    pub mean: f64,
    pub std: f64,
    pub n: usize,
}

impl Stat {
    pub fn of(values: &[f64]) -> Stat {
        let n = values.len();
        if n == 0 {
            return Stat::default();
        }
        let mean = values.iter().sum::<f64>() / n as f64;
        let var =
            if n > 1 { values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64 } else { 0.0 };
        Stat { mean, std: var.sqrt(), n }
    }
}

/// One setting at one sample count.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    pub spp: u32,
    pub rmse: Stat,
    pub relmse: Stat,
    pub rmse_border: Stat,
    pub render_seconds: Stat,
    pub filter_seconds: Stat,
    /// The unfiltered spp with the same RMSE, and its render seconds (filtered settings only).
    pub equal_spp: Option<f64>,
    pub equal_seconds: Option<f64>,
}

/// A setting's curve.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub choice: Choice,
    /// The sampler, where a run compares several (it then prefixes the label).
    pub sampler: Option<SamplerKind>,
    pub points: Vec<Point>,
}

impl Series {
    /// The setting's label, after its sampler's name where a run compares samplers.
    pub fn label(&self) -> String {
        match self.sampler {
            Some(s) => format!("{s} {}", self.choice.label()),
            None => self.choice.label(),
        }
    }
}

/// Every setting's curve.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    pub series: Vec<Series>,
}

/// Piecewise-linear interpolation of y(x) in log-log space through `pts` (sorted by x),
/// extrapolated beyond the ends along the least-squares line of all points.
pub fn loglog(pts: &[(f64, f64)], x: f64) -> Option<f64> {
    let pts: Vec<(f64, f64)> =
        pts.iter().filter(|(a, b)| *a > 0.0 && *b > 0.0).map(|(a, b)| (a.ln(), b.ln())).collect();
    if pts.len() < 2 || x <= 0.0 {
        return None;
    }
    let lx = x.ln();
    for w in pts.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if (x0..=x1).contains(&lx) && x1 > x0 {
            return Some((y0 + (y1 - y0) * (lx - x0) / (x1 - x0)).exp());
        }
    }
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    if sxx == 0.0 {
        return None;
    }
    let slope = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum::<f64>() / sxx;
    Some((my + slope * (lx - mx)).exp())
}

/// The x at which the decreasing log-log curve `pts` (sorted by x) reaches `y`: interpolated
/// between the points that bracket it, else extrapolated along the least-squares line.
pub fn inverse_loglog(pts: &[(f64, f64)], y: f64) -> Option<f64> {
    let swapped: Vec<(f64, f64)> = pts.iter().map(|&(a, b)| (b, a)).collect();
    let mut sorted = swapped.clone();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    loglog(&sorted, y)
}

impl Table {
    pub fn new(rows: &[Row], choices: &[Choice], spps: &[u32]) -> Table {
        let mut series: Vec<Series> = choices
            .iter()
            .map(|c| {
                let key = c.key();
                let points = spps
                    .iter()
                    .filter_map(|&spp| {
                        let rs: Vec<&Row> = rows.iter().filter(|r| r.spp == spp && r.key() == key).collect();
                        if rs.is_empty() {
                            return None;
                        }
                        let stat =
                            |f: fn(&Row) -> f64| Stat::of(&rs.iter().map(|r| f(r)).collect::<Vec<_>>());
                        Some(Point {
                            spp,
                            rmse: stat(|r| r.rmse),
                            relmse: stat(|r| r.relmse),
                            rmse_border: stat(|r| r.rmse_border),
                            render_seconds: stat(|r| r.render_seconds),
                            filter_seconds: stat(|r| r.filter_seconds),
                            equal_spp: None,
                            equal_seconds: None,
                        })
                    })
                    .collect();
                Series { choice: c.clone(), sampler: None, points }
            })
            .collect();
        // The unfiltered curves: RMSE and render seconds against spp.
        let base = series.iter().find(|s| s.choice.is_base()).cloned();
        if let Some(base) = base {
            let err: Vec<(f64, f64)> = base.points.iter().map(|p| (p.spp as f64, p.rmse.mean)).collect();
            let time: Vec<(f64, f64)> =
                base.points.iter().map(|p| (p.spp as f64, p.render_seconds.mean)).collect();
            for s in series.iter_mut().filter(|s| !s.choice.is_base()) {
                for p in &mut s.points {
                    p.equal_spp = inverse_loglog(&err, p.rmse.mean);
                    p.equal_seconds = p.equal_spp.and_then(|n| loglog(&time, n));
                }
            }
        }
        Table { series }
    }

    /// The table with every series labelled by `sampler`.
    pub fn labelled(mut self, sampler: SamplerKind) -> Table {
        for s in &mut self.series {
            s.sampler = Some(sampler);
        }
        self
    }

    /// The uniform unfiltered curve.
    fn base(&self) -> Option<&Series> {
        self.series.iter().find(|s| s.choice.is_base())
    }

    /// The table as Markdown.
    pub fn markdown(&self) -> String {
        let mut md = String::from(
            "| setting | spp | RMSE (mean ± sd) | relMSE | render s | filter s | unfiltered spp for this RMSE | worth | its render s |\n\
             | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n",
        );
        for s in &self.series {
            for p in &s.points {
                let (eq, worth, secs) = match (p.equal_spp, p.equal_seconds) {
                    (Some(n), t) => (
                        format!("{n:.0}"),
                        format!("{:.1}x", n / p.spp as f64),
                        t.map_or("-".into(), |t| format!("{t:.2}")),
                    ),
                    _ => ("-".into(), "-".into(), "-".into()),
                };
                let _ = writeln!(
                    md,
                    "| {} | {} | {:.4e} ± {:.1e} | {:.3e} | {:.3} | {:.4} | {eq} | {worth} | {secs} |",
                    s.label(),
                    p.spp,
                    p.rmse.mean,
                    p.rmse.std,
                    p.relmse.mean,
                    p.render_seconds.mean,
                    p.filter_seconds.mean,
                );
            }
        }
        md
    }
}

/// How `test` compares with `against` at one spp, from their means and spreads over seeds:
/// "better" or "worse" when the means differ by more than twice the standard error of their
/// difference, else "same".
fn verdict(test: &Stat, against: &Stat) -> &'static str {
    let se = (test.std.powi(2) / test.n.max(1) as f64 + against.std.powi(2) / against.n.max(1) as f64).sqrt();
    if test.mean + 2.0 * se < against.mean {
        "better"
    } else if test.mean - 2.0 * se > against.mean {
        "worse"
    } else {
        "same"
    }
}

/// What one sampler is worth against another at each spp of their unfiltered curves: the
/// samples `base` needs for `test`'s RMSE, over `test`'s spp (read off `base`'s log-log curve).
pub struct Worth {
    pub spp: u32,
    pub base: Stat,
    pub test: Stat,
    /// The samples factor, and its range for `test`'s mean RMSE +- twice its standard error.
    pub worth: Option<f64>,
    pub range: Option<(f64, f64)>,
    pub verdict: &'static str,
}

/// [`Worth`] of `test`'s unfiltered curve against `base`'s, at each spp both measured; no
/// factor where `base`'s error does not fall with the samples, and no range where `test`'s
/// spread reaches zero.
pub fn worth(base: &Table, test: &Table) -> Vec<Worth> {
    let (Some(b), Some(t)) = (base.base(), test.base()) else { return Vec::new() };
    let curve: Vec<(f64, f64)> = b.points.iter().map(|p| (p.spp as f64, p.rmse.mean)).collect();
    // A base whose error does not fall with the samples (fireflies dominating it) has no
    // samples to read off: the verdict alone is given.
    let falls = curve.windows(2).all(|w| w[1].1 < w[0].1);
    t.points
        .iter()
        .filter_map(|p| {
            let q = b.points.iter().find(|q| q.spp == p.spp)?;
            let spp = p.spp as f64;
            let at =
                |rmse: f64| inverse_loglog(&curve, rmse).filter(|_| falls && rmse > 0.0).map(|n| n / spp);
            let se = p.rmse.std / (p.rmse.n.max(1) as f64).sqrt();
            let range = at(p.rmse.mean + 2.0 * se).zip(at(p.rmse.mean - 2.0 * se));
            Some(Worth {
                spp: p.spp,
                base: q.rmse,
                test: p.rmse,
                worth: at(p.rmse.mean),
                range,
                verdict: verdict(&p.rmse, &q.rmse),
            })
        })
        .collect()
}

/// The Markdown comparison of the samplers in `tables` (the first is the base): what each is
/// worth in samples unfiltered, then what each filter gains under each.
pub fn samplers_markdown(tables: &[(SamplerKind, Table)]) -> String {
    let mut md = String::new();
    let Some((base_kind, base)) = tables.first() else { return md };
    for (kind, table) in &tables[1..] {
        let _ = writeln!(
            md,
            "**{kind} against {base_kind}, unfiltered.** \"worth\" is the samples {base_kind} sampling \
             needs for {kind}'s RMSE, over {kind}'s samples (read off {base_kind}'s log-log curve); \
             its range is for {kind}'s mean RMSE +- twice its standard error over seeds; the verdict \
             compares the means against twice the standard error of their difference.\n"
        );
        md.push_str(&format!(
            "| spp | {base_kind} RMSE | {kind} RMSE | {kind} is worth | range | verdict |\n| --- | --- | --- | --- | --- | --- |\n"
        ));
        for w in worth(base, table) {
            let _ = writeln!(
                md,
                "| {} | {:.4e} ± {:.1e} | {:.4e} ± {:.1e} | {} | {} | {} |",
                w.spp,
                w.base.mean,
                w.base.std,
                w.test.mean,
                w.test.std,
                w.worth.map_or("-".into(), |x| format!("{x:.2}x")),
                w.range.map_or("-".into(), |(a, b)| format!("{a:.2}x-{b:.2}x")),
                w.verdict
            );
        }
        md.push('\n');
    }
    // The filters' gain (filtered RMSE over unfiltered) under each sampler.
    let filtered: Vec<&Series> =
        base.series.iter().filter(|s| s.choice.kernel.is_some() && s.choice.adaptive.is_none()).collect();
    if filtered.is_empty() {
        return md;
    }
    let names: Vec<String> = tables.iter().map(|(k, _)| k.to_string()).collect();
    let _ = writeln!(
        md,
        "**Each filter's RMSE over the unfiltered RMSE of the same renders, under each sampler** \
         (below 1: the filter helps; the paper's filters assume noise uncorrelated between pixels).\n"
    );
    let _ = writeln!(md, "| setting | spp | {} |", names.join(" | "));
    let _ = writeln!(md, "| --- | --- |{}", " --- |".repeat(names.len()));
    for s in filtered {
        for p in &s.points {
            let gains: Vec<String> = tables
                .iter()
                .map(|(_, t)| {
                    let of = |choice: &Choice| {
                        t.series.iter().find(|x| &x.choice == choice)?.points.iter().find(|q| q.spp == p.spp)
                    };
                    match (of(&s.choice), t.base().and_then(|b| b.points.iter().find(|q| q.spp == p.spp))) {
                        (Some(f), Some(b)) if b.rmse.mean > 0.0 => {
                            format!("{:.3}", f.rmse.mean / b.rmse.mean)
                        }
                        _ => "-".into(),
                    }
                })
                .collect();
            let _ = writeln!(md, "| {} | {} | {} |", s.choice.label(), p.spp, gains.join(" | "));
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loglog_interpolates_and_extrapolates_a_power_law() {
        // RMSE = 0.4 / sqrt(spp): exact on and between the points, and beyond them.
        let pts: Vec<(f64, f64)> =
            [1.0, 4.0, 16.0, 64.0].iter().map(|&s: &f64| (s, 0.4 / s.sqrt())).collect();
        for spp in [2.0, 10.0, 64.0, 256.0, 0.5] {
            let want = 0.4 / f64::sqrt(spp);
            let got = loglog(&pts, spp).expect("value");
            assert!((got / want - 1.0).abs() < 1e-9, "{spp}: {got} vs {want}");
            let back = inverse_loglog(&pts, want).expect("inverse");
            assert!((back / spp - 1.0).abs() < 1e-9, "{spp}: {back}");
        }
        assert_eq!(loglog(&pts[..1], 2.0), None);
    }

    #[test]
    fn equal_quality_reads_the_unfiltered_curve() {
        let row = |filter: &str, spp: u32, rmse: f64| Row {
            scene: "s".into(),
            accel: "embree".into(),
            sampler: crate::render::sampler::SamplerKind::Independent,
            spp,
            seed: 0,
            filter: filter.into(),
            target: if filter == "none" { "none" } else { "indirect" }.into(),
            edge_aware: super::super::Edge::Off,
            render_seconds: spp as f64 * 0.01,
            filter_seconds: 0.001,
            sse: 0.0,
            rmse,
            relmse: 0.0,
            rmse_border: 0.0,
            run: String::new(),
        };
        let spps = [4u32, 16, 64];
        let mut rows: Vec<Row> = spps.iter().map(|&s| row("none", s, 0.4 / (s as f64).sqrt())).collect();
        // A filter that halves the error everywhere is worth four times the samples.
        rows.extend(spps.iter().map(|&s| row("weighted3", s, 0.2 / (s as f64).sqrt())));
        let choices = super::super::choices(
            &["none".into(), "weighted3".into()],
            &[crate::filter::Target::Indirect],
            &[super::super::Edge::Off],
        )
        .expect("choices");
        let t = Table::new(&rows, &choices, &spps);
        let filtered = &t.series[1];
        for p in &filtered.points {
            let n = p.equal_spp.expect("equal spp");
            assert!((n / p.spp as f64 - 4.0).abs() < 1e-9, "{n}");
            assert!((p.equal_seconds.expect("seconds") - n * 0.01).abs() < 1e-9);
        }
        assert!(t.markdown().contains("4.0x"));
    }

    #[test]
    fn a_sampler_at_half_the_error_is_worth_four_times_the_samples() {
        use crate::render::sampler::SamplerKind;
        let row = |sampler: SamplerKind, spp: u32, seed: u32, rmse: f64| Row {
            scene: "s".into(),
            accel: "embree".into(),
            sampler,
            spp,
            seed,
            filter: "none".into(),
            target: "none".into(),
            edge_aware: super::super::Edge::Off,
            render_seconds: 1.0,
            filter_seconds: 0.0,
            sse: 0.0,
            rmse,
            relmse: 0.0,
            rmse_border: 0.0,
            run: String::new(),
        };
        let spps = [4u32, 16, 64];
        let choices = [Choice::none()];
        // Two seeds a point, 1% apart.
        let table = |sampler, scale: f64| {
            let rows: Vec<Row> = spps
                .iter()
                .flat_map(|&s| {
                    (0..2)
                        .map(move |k| row(sampler, s, k, scale * (1.0 + 0.01 * k as f64) / (s as f64).sqrt()))
                })
                .collect();
            Table::new(&rows, &choices, &spps)
        };
        let independent = table(SamplerKind::Independent, 0.4);
        let sobol = table(SamplerKind::Sobol, 0.2);
        for w in worth(&independent, &sobol) {
            let n = w.worth.expect("a factor");
            assert!((n - 4.0).abs() < 1e-9, "{}: {n}", w.spp);
            let (lo, hi) = w.range.expect("a range");
            assert!(lo < n && n < hi, "{lo} {n} {hi}");
            assert_eq!(w.verdict, "better");
        }
        // Against itself: the same, worth 1x.
        assert!(worth(&independent, &independent).iter().all(|w| w.verdict == "same"));
        // A base whose error does not fall with the samples has no factor to give.
        let flat: Vec<Row> = spps.iter().map(|&s| row(SamplerKind::Independent, s, 0, 0.3)).collect();
        let flat = Table::new(&flat, &choices, &spps);
        assert!(worth(&flat, &sobol).iter().all(|w| w.worth.is_none() && w.verdict == "better"));
        let md = samplers_markdown(&[(SamplerKind::Independent, independent), (SamplerKind::Sobol, sobol)]);
        assert!(md.contains("| 16 |") && md.contains("4.00x"), "{md}");
    }
}
