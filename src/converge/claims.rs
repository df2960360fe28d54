//! The paper's claims (section 4, Figures 5 and 6), each checked against a `converge` table and
//! stated with the numbers that decide it: whether it holds here, and where it does not.

use std::fmt::Write as _;

use super::summary::{Point, Series, Table};
use super::Edge;
use crate::filter::Target;

fn find<'a>(table: &'a Table, filter: &str, target: Target, edge: Edge) -> Option<&'a Series> {
    table.series.iter().find(|s| {
        !s.points.is_empty()
            && s.choice.filter == filter
            && s.choice.kernel.is_some() == (filter != "none")
            && s.choice.adaptive.is_none()
            && s.choice.target == target
            && s.choice.edge_aware == edge
    })
}

fn unfiltered(table: &Table) -> Option<&Series> {
    table.series.iter().find(|s| s.choice.is_base())
}

/// RMSE of `s` over the unfiltered RMSE at each spp both have.
fn ratios(s: &Series, base: &Series) -> Vec<(u32, f64)> {
    s.points
        .iter()
        .filter_map(|p| {
            let b = base.points.iter().find(|b| b.spp == p.spp)?;
            (b.rmse.mean > 0.0).then(|| (p.spp, p.rmse.mean / b.rmse.mean))
        })
        .collect()
}

fn list(r: &[(u32, f64)]) -> String {
    r.iter().map(|(spp, x)| format!("{spp}: {x:.2}")).collect::<Vec<_>>().join(", ")
}

/// Markdown: one paragraph a claim, with a verdict (holds / partly / does not hold / not measured).
pub fn check(table: &Table) -> String {
    let mut md = String::new();
    let Some(base) = unfiltered(table) else {
        return "No unfiltered rows: nothing to judge the claims by.\n".into();
    };

    // Figure 5(a): filtering the whole image helps only at low spp, hurts beyond about 50.
    let _ = writeln!(
        md,
        "**Filtering the whole image helps only at low spp and hurts beyond about 50 spp (Figure 5(a)).**"
    );
    let mut any = false;
    for k in ["box3", "weighted3", "median3", "box5"] {
        let Some(s) = find(table, k, Target::Image, Edge::Off) else { continue };
        any = true;
        let r = ratios(s, base);
        let first_hurt = r.iter().find(|(_, x)| *x >= 1.0).map(|(spp, _)| *spp);
        let helps_first = r.first().is_some_and(|(_, x)| *x < 1.0);
        let monotone =
            first_hurt.is_none_or(|h| r.iter().filter(|(spp, _)| *spp >= h).all(|(_, x)| *x >= 1.0));
        let verdict = match first_hurt {
            Some(h) if helps_first && monotone && (16..=128).contains(&h) => {
                format!("holds: it starts to hurt at {h} spp")
            }
            Some(h) if helps_first => format!("partly: it helps at first and hurts from {h} spp"),
            Some(_) => "does not hold: it hurts from the lowest spp".into(),
            None => format!(
                "does not hold here: it still helps at {} spp, the most measured",
                r.last().map_or(0, |p| p.0)
            ),
        };
        let _ = writeln!(md, "- `{k}` on the image, RMSE over unfiltered by spp ({}): {verdict}.", list(&r));
    }
    if !any {
        let _ = writeln!(md, "- not measured (run with `--targets image`).");
    }

    // Figure 5(b): filtering only L_rdd lowers the error at every spp, by half or more at 200.
    let _ = writeln!(
        md,
        "\n**Filtering only L_rdd lowers the error at every spp tested, by half or more even at 200 spp (Figure 5(b)).**"
    );
    match find(table, "weighted3", Target::Indirect, Edge::Off) {
        Some(s) => {
            let r = ratios(s, base);
            let all_lower = r.iter().all(|(_, x)| *x < 1.0);
            let near200 = r.iter().min_by_key(|(spp, _)| (*spp as i64 - 200).abs()).copied();
            let verdict = match (all_lower, near200) {
                (true, Some((spp, x))) if x <= 0.5 => format!("holds: lower at every spp, {x:.2}x at {spp} spp"),
                (true, Some((spp, x))) => format!(
                    "partly: lower at every spp, but {x:.2}x at {spp} spp, not half (an improvement of {:.0}%, where the paper reports more than 100%)",
                    (1.0 / x - 1.0) * 100.0
                ),
                (false, _) => "does not hold: at some spp the filtered error is higher".into(),
                (true, None) => "not measured".into(),
            };
            let _ = writeln!(
                md,
                "- `weighted3` on indirect, RMSE over unfiltered by spp ({}): {verdict}.",
                list(&r)
            );
        }
        None => {
            let _ = writeln!(md, "- not measured (run with `--filters ...,weighted3 --targets indirect`).");
        }
    }

    // Which filter does best at the highest spp.
    let _ =
        writeln!(md, "\n**`weighted3` does best at higher spp, `median3` close behind, `box3` blurs most.**");
    let at_top: Vec<(&str, &Point)> = ["box3", "weighted3", "median3", "box5"]
        .iter()
        .filter_map(|k| {
            find(table, k, Target::Indirect, Edge::Off).and_then(|s| s.points.last()).map(|p| (*k, p))
        })
        .collect();
    if at_top.len() >= 2 {
        let mut ranked = at_top.clone();
        ranked.sort_by(|a, b| a.1.rmse.mean.total_cmp(&b.1.rmse.mean));
        let order: Vec<String> = ranked.iter().map(|(k, p)| format!("`{k}` {:.3e}", p.rmse.mean)).collect();
        let spp = ranked[0].1.spp;
        let (best, top) = (ranked[0].0, ranked[0].1);
        let w3 = ranked.iter().find(|(k, _)| *k == "weighted3").map(|(_, p)| *p);
        // Differences within the spread over seeds (or 1%) are ties, not rankings.
        let tie = |a: &Point, b: &Point| {
            (a.rmse.mean - b.rmse.mean).abs() <= (a.rmse.std + b.rmse.std).max(0.01 * b.rmse.mean)
        };
        let verdict = match w3 {
            _ if best == "weighted3" => "holds for the best filter".to_string(),
            Some(w) if tie(w, top) => format!("a tie here: `weighted3` is within the noise of `{best}`"),
            _ => format!("does not hold here: `{best}` does best"),
        };
        let _ = writeln!(md, "- on indirect at {spp} spp, best first: {}; {verdict}.", order.join(", "));
    } else {
        let _ = writeln!(md, "- not measured (needs at least two of box3, weighted3, median3 on indirect).");
    }

    // Figure 6(b): edge-aware filtering removes most of the error left along object borders.
    let _ = writeln!(
        md,
        "\n**Edge-aware filtering removes most of the error left along object borders (Figure 6(b)).**"
    );
    match (
        find(table, "weighted3", Target::Indirect, Edge::Off),
        find(table, "weighted3", Target::Indirect, Edge::On),
    ) {
        (Some(plain), Some(edge)) => {
            for (p, e) in plain.points.iter().zip(&edge.points) {
                let b = base.points.iter().find(|b| b.spp == p.spp);
                let left = if p.rmse_border.mean > 0.0 {
                    (e.rmse_border.mean / p.rmse_border.mean).powi(2)
                } else {
                    1.0
                };
                let _ = writeln!(
                    md,
                    "- {} spp: RMSE on border pixels unfiltered {}, `weighted3` {:.3e}, edge-aware {:.3e}: {:.0}% of the plain filter's squared border error removed.",
                    p.spp,
                    b.map_or("-".to_string(), |b| format!("{:.3e}", b.rmse_border.mean)),
                    p.rmse_border.mean,
                    e.rmse_border.mean,
                    (1.0 - left) * 100.0
                );
            }
            let last = plain.points.last().zip(edge.points.last());
            let verdict = match last {
                Some((p, e))
                    if p.rmse_border.mean > 0.0
                        && (e.rmse_border.mean / p.rmse_border.mean).powi(2) <= 0.5 =>
                {
                    "holds at the highest spp"
                }
                _ => "does not hold at the highest spp: less than half the border error is removed",
            };
            let _ = writeln!(md, "- {verdict}.");
            // Beyond the paper: the coverage stop, which leaves mixed border pixels alone.
            if let Some(pure) = find(table, "weighted3", Target::Indirect, Edge::Pure) {
                let r = ratios(pure, base);
                for (p, q) in plain.points.iter().zip(&pure.points) {
                    if p.rmse_border.mean > 0.0 {
                        let left = (q.rmse_border.mean / p.rmse_border.mean).powi(2);
                        let _ = writeln!(
                            md,
                            "- beyond the paper, `--edge-pure` at {} spp: border RMSE {:.3e}, {:.0}% of the plain filter's squared border error removed.",
                            p.spp,
                            q.rmse_border.mean,
                            (1.0 - left) * 100.0
                        );
                    }
                }
                let _ = writeln!(
                    md,
                    "- with `--edge-pure`, the whole image's RMSE over unfiltered by spp: {}.",
                    list(&r)
                );
            }
        }
        _ => {
            let _ = writeln!(md, "- not measured (run with `--edge-aware off,on`).");
        }
    }
    md
}

#[cfg(test)]
mod tests {
    use super::super::summary::Table;
    use super::super::{choices, Row};
    use super::*;

    /// A setting of a test table: filter, target, edge-aware, and its RMSE over the unfiltered.
    type Setting = (&'static str, &'static str, bool, fn(u32) -> f64);

    /// Rows where the unfiltered RMSE is 0.4/sqrt(spp) and each setting scales it by `f(spp)`.
    fn table(settings: &[Setting]) -> Table {
        let spps = [1u32, 4, 16, 64, 256];
        let mut rows = Vec::new();
        for &spp in &spps {
            let base = 0.4 / (spp as f64).sqrt();
            let mut push = |filter: &str, target: &str, edge: bool, rmse: f64, border: f64| {
                rows.push(Row {
                    scene: "s".into(),
                    accel: "embree".into(),
                    sampler: crate::render::sampler::SamplerKind::Independent,
                    spp,
                    seed: 0,
                    filter: filter.into(),
                    target: target.into(),
                    edge_aware: if edge { Edge::On } else { Edge::Off },
                    render_seconds: 1.0,
                    filter_seconds: 0.001,
                    sse: 0.0,
                    rmse,
                    relmse: 0.0,
                    rmse_border: border,
                    run: String::new(),
                })
            };
            push("none", "none", false, base, base);
            for &(f, t, e, scale) in settings {
                push(f, t, e, base * scale(spp), if e { 0.01 } else { 0.1 });
            }
        }
        let ch = choices(
            &["none".into(), "box3".into(), "weighted3".into(), "median3".into()],
            &[Target::Indirect, Target::Image],
            &[Edge::Off, Edge::On],
        )
        .expect("choices");
        Table::new(&rows, &ch, &spps)
    }

    #[test]
    fn verdicts_follow_the_numbers() {
        let t = table(&[
            ("weighted3", "image", false, |spp| if spp < 64 { 0.6 } else { 1.5 }),
            ("box3", "image", false, |_| 0.7),
            ("weighted3", "indirect", false, |_| 0.45),
            ("median3", "indirect", false, |_| 0.5),
            ("box3", "indirect", false, |_| 0.8),
            ("weighted3", "indirect", true, |_| 0.4),
        ]);
        let md = check(&t);
        assert!(
            md.contains("`weighted3` on the image") && md.contains("holds: it starts to hurt at 64 spp"),
            "{md}"
        );
        assert!(
            md.contains("`box3` on the image")
                && md.contains("does not hold here: it still helps at 256 spp"),
            "{md}"
        );
        assert!(md.contains("holds: lower at every spp, 0.45x at 256 spp"), "{md}");
        assert!(md.contains("holds for the best filter"), "{md}");
        // Border RMSE 0.1 plain, 0.01 edge-aware: 99% removed.
        assert!(
            md.contains("99% of the plain filter's squared border error removed")
                && md.contains("holds at the highest spp"),
            "{md}"
        );

        let t = table(&[
            ("weighted3", "indirect", false, |spp| if spp < 200 { 0.8 } else { 1.1 }),
            ("median3", "indirect", false, |_| 0.5),
        ]);
        let md = check(&t);
        assert!(md.contains("does not hold: at some spp the filtered error is higher"), "{md}");
        assert!(md.contains("does not hold here: `median3` does best"), "{md}");
        assert!(md.contains("not measured (run with `--edge-aware off,on`)"), "{md}");
    }
}
