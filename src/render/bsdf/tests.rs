//! The BSDFs' tests: chi-square tests of their sampling through the interface the integrator
//! uses, reciprocity, energy bounds, Fresnel and Snell.

use super::*;
use crate::math::chi_square::z_score;
use crate::math::{cosine_hemisphere, Frame};

fn wo(theta_deg: f32) -> Vec3 {
    let t = theta_deg.to_radians();
    Vec3::new(t.sin(), 0.0, t.cos())
}

/// Checks a BSDF's non-delta lobes through the interface the integrator uses, at normal `n`:
/// the directions `sample` gives above the surface follow `pdf` (a direction through the
/// surface counts as none), and each non-delta sample's pdf and weight are those of a lobe of
/// its kind (several lobes may share a kind: the one of the sample's density), f cos / pdf.
fn check_through_the_interface<B: Bsdf>(name: &str, b: &B, wo: Vec3, n: Vec3) {
    let above = |s: &mut crate::render::sampler::Sampler| {
        b.sample(wo, s).filter(|bs| n.dot(bs.wi) > 0.0 && !bs.lobe.is_delta()).map(|bs| bs.wi)
    };
    let z = z_score(above, |d| if n.dot(d) > 0.0 { b.pdf(wo, d) } else { 0.0 });
    assert!(z < 4.0, "{name}: z = {z}");
    let mut s = crate::render::sampler::Sampler::new(3, 1, 4);
    let mut checked = 0;
    // Until 2,000 non-delta samples are checked (a mostly transmitting BSDF gives few).
    for _ in 0..100_000 {
        if checked == 2000 {
            break;
        }
        let Some(bs) = b.sample(wo, &mut s) else { continue };
        let cos = n.dot(bs.wi);
        if cos <= 1e-3 || bs.pdf <= 1e-3 || bs.lobe.is_delta() {
            continue;
        }
        let mut lobe: Option<(Vec3, f32)> = None;
        b.eval_lobes(wo, bs.wi, |l, f, pdf| {
            if l == bs.lobe && lobe.is_none_or(|(_, p)| (p - bs.pdf).abs() > (pdf - bs.pdf).abs()) {
                lobe = Some((f, pdf));
            }
        });
        let Some((f, pdf)) = lobe else { panic!("{name}: sampled lobe {:?} has no value", bs.lobe) };
        assert!((bs.pdf - pdf).abs() <= 1e-3 * pdf, "{name}: pdf {} vs {pdf}", bs.pdf);
        let weight = f * cos / pdf;
        let tolerance = 1e-3 * (1.0 + weight.max_element());
        assert!((bs.weight - weight).abs().max_element() <= tolerance, "{name}: {} vs {weight}", bs.weight);
        checked += 1;
    }
    assert!(checked > 1000, "{name}: {checked} samples checked");
}

#[test]
fn diffuse_and_glossy_sample_their_density_at_a_tilted_normal() {
    let n = Vec3::new(0.3, -0.5, 0.8).normalize();
    let wo = Vec3::new(-0.2, 0.4, 0.9).normalize();
    check_through_the_interface("diffuse", &Diffuse { albedo: Vec3::new(0.7, 0.5, 0.2), n }, wo, n);
    let lobes = GlossyLobes { specular: Vec3::splat(0.04), alpha: 0.3, base: Vec3::new(0.6, 0.3, 0.2) };
    check_through_the_interface("glossy", &Glossy { lobes, frame: Frame::new(n) }, wo, n);
}

#[test]
fn a_wrong_density_through_the_interface_fails() {
    // The check has power: a Lambertian judged by a density tilted the other way fails.
    let n = Vec3::new(0.3, -0.5, 0.8).normalize();
    let wo = n;
    let b = Diffuse { albedo: Vec3::ONE, n };
    let other = Diffuse { n: Vec3::new(-0.3, -0.5, 0.8).normalize(), ..b };
    let z =
        z_score(|s| b.sample(wo, s).map(|bs| bs.wi), |d| if n.dot(d) > 0.0 { other.pdf(wo, d) } else { 0.0 });
    assert!(z > 10.0, "z = {z}");
}

#[test]
fn alpha_is_the_square_of_roughness_above_the_floor() {
    assert_eq!(alpha(0.5), 0.25);
    assert_eq!(alpha(1.0), 1.0);
    assert_eq!(alpha(0.0), MIN_ALPHA);
}

#[test]
fn ggx_visible_normal_sampling_matches_its_density() {
    for (alpha, theta) in [(0.3, 0.0), (0.3, 60.0), (0.6, 30.0), (1.0, 80.0)] {
        let g = GlossyLobes { specular: Vec3::splat(0.9), alpha, base: Vec3::ZERO };
        let wo = wo(theta);
        let z = z_score(|s| Some(g.sample_specular(wo, s.next_2d())), |d| g.pdf_specular(wo, d));
        assert!(z < 4.0, "alpha {alpha}, theta {theta}: z = {z}");
    }
}

#[test]
fn both_lobes_together_match_the_mixture_density() {
    let g = GlossyLobes { specular: Vec3::splat(0.04), alpha: 0.4, base: Vec3::new(0.7, 0.2, 0.1) };
    let wo = wo(45.0);
    let p = g.specular_probability(wo);
    assert!(p > 0.0 && p < 1.0, "{p}");
    let z = z_score(|s| Some(g.sample(wo, s.next_1d(), s.next_2d()).0), |d| g.pdf(wo, d));
    assert!(z < 4.0, "z = {z}");
}

#[test]
fn a_wrong_ggx_density_fails() {
    // The test has power: a lobe judged by the density of a rougher one must fail.
    let g = GlossyLobes { specular: Vec3::ONE, alpha: 0.3, base: Vec3::ZERO };
    let rough = GlossyLobes { alpha: 0.36, ..g };
    let wo = wo(30.0);
    let z = z_score(|s| Some(g.sample_specular(wo, s.next_2d())), |d| rough.pdf_specular(wo, d));
    assert!(z > 10.0, "z = {z}");
}

#[test]
fn the_sampling_weight_is_f_cos_over_pdf() {
    let g = GlossyLobes { specular: Vec3::new(0.9, 0.5, 0.2), alpha: 0.25, base: Vec3::ZERO };
    let wo = wo(50.0);
    let mut s = crate::render::sampler::Sampler::new(1, 2, 3);
    for _ in 0..1000 {
        let wi = g.sample_specular(wo, s.next_2d());
        if wi.z <= 1e-3 {
            continue;
        }
        let direct = g.eval_specular(wo, wi) * wi.z / g.pdf_specular(wo, wi);
        let weight = g.specular_weight(wo, wi);
        assert!((direct - weight).abs().max_element() < 1e-4 * (1.0 + weight.max_element()), "{wi}");
    }
}

#[test]
fn reciprocal_and_energy_bounded() {
    let mut s = crate::render::sampler::Sampler::new(4, 5, 6);
    // Reciprocity, f(a, b) = f(b, a), for smooth to rough lobes, with and without a base,
    // dielectric and metallic F0; grazing directions included.
    for (alpha, f0, base) in [
        (0.001, 0.04, Vec3::ONE),
        (0.05, 0.04, Vec3::splat(0.5)),
        (0.3, 0.04, Vec3::ONE),
        (0.3, 0.95, Vec3::ZERO),
        (1.0, 0.5, Vec3::new(0.8, 0.2, 0.1)),
    ] {
        let g = GlossyLobes { specular: Vec3::splat(f0), alpha, base };
        for i in 0..2000 {
            let a = if i % 10 == 0 { wo(89.9) } else { cosine_hemisphere(s.next_2d()) };
            let b = cosine_hemisphere(s.next_2d());
            let (ab, ba) = (g.eval(a, b), g.eval(b, a));
            assert!(ab.is_finite() && ab.min_element() >= 0.0, "alpha {alpha}: f({a}, {b}) = {ab}");
            assert!(
                (ab - ba).abs().max_element() <= 1e-4 * ab.max_element().max(1.0),
                "alpha {alpha}: {a} {b}: {ab} vs {ba}"
            );
        }
    }
    let g = GlossyLobes { specular: Vec3::splat(0.04), alpha: 0.3, base: Vec3::ONE };
    // Directional albedo (the integral of f cos over the hemisphere) stays at or under 1, by
    // importance sampling the mixture with many samples.
    for theta in [0.0f32, 45.0, 75.0, 89.0] {
        let wo = wo(theta);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let (wi, _) = g.sample(wo, s.next_1d(), s.next_2d());
            let pdf = g.pdf(wo, wi);
            if pdf > 0.0 && wi.z > 0.0 {
                sum += (g.eval(wo, wi).max_element() * wi.z / pdf) as f64;
            }
        }
        let albedo = sum / n as f64;
        // Standard error well under 0.005 at 200k samples. Single-scattering GGX loses the
        // light that would bounce between microfacets, most at grazing angles (0.22 at 89
        // degrees here), but near the normal almost nothing is lost.
        assert!(albedo <= 1.0 + 0.01, "theta {theta}: albedo {albedo}");
        if theta == 0.0 {
            assert!(albedo > 0.9, "albedo {albedo}");
        }
    }
}

#[test]
fn fresnel_at_normal_incidence_grazing_and_beyond_the_critical_angle() {
    assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
    assert!((fresnel_dielectric(1e-4, 1.5) - 1.0).abs() < 1e-2);
    // From inside glass (eta = 1/1.5) beyond asin(1/1.5) = 41.8 degrees: total reflection.
    assert_eq!(fresnel_dielectric(43f32.to_radians().cos(), 1.0 / 1.5), 1.0);
    assert!(fresnel_dielectric(40f32.to_radians().cos(), 1.0 / 1.5) < 1.0);
    // The same boundary crossed either way reflects the same fraction.
    for cos_i in [0.2f32, 0.5, 0.9] {
        let sin_t = (1.0 - cos_i * cos_i).sqrt() / 1.5;
        let cos_t = (1.0 - sin_t * sin_t).sqrt();
        assert!((fresnel_dielectric(cos_i, 1.5) - fresnel_dielectric(cos_t, 1.0 / 1.5)).abs() < 1e-5);
    }
}

/// Mirror and glass are delta BSDFs: reciprocity means each specular map is reversible (the
/// light can run the path backwards) with the same weight. Reflection is an involution; a
/// refracted direction refracted back from the other side is the incident one; and Fresnel
/// reflectance is the same from both sides of a boundary (Stokes), so the transmitted
/// weights (1 - F) / eta^2 and (1 - F) eta^2 of the two directions differ exactly by the
/// radiance scaling 1 / eta^2 that makes the pair adjoint.
#[test]
fn mirror_and_glass_are_reciprocal() {
    let n = Vec3::Z;
    let mut s = crate::render::sampler::Sampler::new(9, 9, 9);
    let mut refracted = 0;
    for _ in 0..2000 {
        let wo = cosine_hemisphere(s.next_2d());
        let wr = reflect(wo, n);
        assert!((reflect(wr, n) - wo).length() < 1e-5 && (wr.z - wo.z).abs() < 1e-6, "{wo}");
        for eta in [1.5f32, 1.0 / 1.5, 2.42, 1.0 / 1.33] {
            let cos_i = wo.z;
            let f = fresnel_dielectric(cos_i, eta);
            if f >= 1.0 {
                continue; // total internal reflection: only the mirror map, tested above
            }
            refracted += 1;
            let wt = refract(wo, n, eta, cos_i);
            // Backwards: wt, now the direction away from the surface on the other side.
            let cos_t = wt.dot(-n);
            let back = refract(wt, -n, 1.0 / eta, cos_t);
            assert!((back - wo).length() < 1e-4, "eta {eta}: {wo} -> {wt} -> {back}");
            let f_back = fresnel_dielectric(cos_t, 1.0 / eta);
            assert!((f - f_back).abs() < 1e-4, "eta {eta}, cos {cos_i}: F {f} vs {f_back}");
        }
    }
    assert!(refracted > 6000, "{refracted} refractions tested");
}

#[test]
fn refraction_obeys_snell() {
    let n = Vec3::Z;
    let wo = Vec3::new(0.6, 0.0, 0.8);
    let wt = refract(wo, n, 1.5, wo.dot(n));
    let sin_i = 0.6;
    let sin_t = (1.0 - wt.z * wt.z).sqrt();
    assert!((sin_i - 1.5 * sin_t).abs() < 1e-5, "{wt}");
    assert!(wt.z < 0.0 && wt.x < 0.0, "goes through, on the far side of the normal: {wt}");
    assert!((reflect(wo, n) - Vec3::new(-0.6, 0.0, 0.8)).length() < 1e-6);
}

/// The metallic-roughness BSDF samples what it evaluates; its GGX lobe is tagged S when
/// smooth and D when rough, the values and densities unchanged; and it conserves energy: a
/// white dielectric reflects all the light (the base takes what the lobe does not), within
/// the loss of GGX's single scattering.
#[test]
fn the_pbr_bsdf_samples_its_density_tags_its_lobe_and_keeps_energy() {
    let lobes = GlossyLobes { specular: Vec3::splat(0.04), alpha: alpha(0.7), base: Vec3::ZERO };
    let pbr = |base: Vec3, rough: bool| Pbr {
        lobes,
        base,
        frame: Frame::new(Vec3::Z),
        base_frame: None,
        rough,
        metallic: 0.0,
        metal: Vec3::ONE,
    };
    let (smooth, rough) = (pbr(Vec3::splat(0.5), false), pbr(Vec3::splat(0.5), true));
    // The base in a frame of its own (a normal map's bent normal under a raised shading one).
    let bent = Pbr { base_frame: Some(Frame::new(Vec3::new(-0.4, 0.2, 1.0).normalize())), ..smooth };
    for theta in [10.0, 45.0, 75.0] {
        check_through_the_interface("smooth pbr", &smooth, wo(theta), Vec3::Z);
        check_through_the_interface("pbr with a bent base", &bent, wo(theta), Vec3::Z);
    }
    assert_eq!((smooth.lobe(), rough.lobe()), (None, Some(Lobe::Diffuse)));
    let mut s = crate::render::sampler::Sampler::new(5, 2, 1);
    let (mut specular, mut diffuse) = (0, 0);
    for _ in 0..500 {
        let mut t = s.clone();
        let (a, b) = (smooth.sample(wo(35.0), &mut s), rough.sample(wo(35.0), &mut t));
        let (Some(a), Some(b)) = (a, b) else { continue };
        assert_eq!((a.wi, a.weight, a.pdf), (b.wi, b.weight, b.pdf));
        assert_eq!(b.lobe, Lobe::Diffuse);
        match a.lobe {
            Lobe::Specular => specular += 1,
            _ => diffuse += 1,
        }
        let (mut fa, mut fb) = (Vec3::ZERO, Vec3::ZERO);
        smooth.eval_lobes(wo(35.0), a.wi, |_, f, _| fa += f);
        rough.eval_lobes(wo(35.0), a.wi, |l, f, _| {
            assert_eq!(l, Lobe::Diffuse);
            fb += f
        });
        assert_eq!(fa, fb);
    }
    assert!(specular > 10 && diffuse > 100, "both lobes sampled: {specular} S, {diffuse} D");
    // A white base under the dielectric lobe: the albedo (the mean sample weight) is one
    // at every angle, the lobe's and the base's shares summing to it.
    let white = pbr(Vec3::ONE, false);
    for theta in [0.0, 40.0, 70.0, 85.0] {
        let mut s = crate::render::sampler::Sampler::new(9, 1, 3);
        let n = 40_000;
        let total: f32 = (0..n).filter_map(|_| white.sample(wo(theta), &mut s)).map(|b| b.weight.x).sum();
        let albedo = total / n as f32;
        assert!((albedo - 1.0).abs() < 0.02, "albedo {albedo} at {theta} degrees");
    }
}

/// A layered BSDF at normal +z: a white dielectric base of roughness 0.5 with none of the
/// layers, which each case then adds.
fn principled() -> Principled {
    let (f0, f90) = dielectric_f0(1.5, 1.0, Vec3::ONE);
    Principled {
        frame: Frame::new(Vec3::Z),
        coat_frame: None,
        base_frame: None,
        entering: true,
        color: Vec3::ONE,
        metallic: 0.0,
        alpha: alpha(0.5),
        f0,
        f90,
        transmission: 0.0,
        ior: 1.5,
        thin: false,
        coat: 0.0,
        coat_alpha: alpha(0.1),
        sheen: SheenLobe::new(Vec3::ZERO, 0.5),
        sheen_roughness: 0.5,
        rough: false,
        coat_rough: false,
    }
}

/// The layered BSDF's cases: name, BSDF.
fn layered_cases() -> Vec<(&'static str, Principled)> {
    let p = principled();
    vec![
        ("dielectric", p),
        ("rough metal", Principled { metallic: 1.0, alpha: alpha(0.8), ..p }),
        ("half metal", Principled { metallic: 0.5, alpha: alpha(0.3), ..p }),
        ("clearcoat", Principled { coat: 1.0, coat_alpha: alpha(0.3), ..p }),
        ("rough clearcoat", Principled { coat: 0.7, coat_alpha: alpha(0.6), ..p }),
        (
            "bent clearcoat",
            Principled {
                coat: 1.0,
                coat_alpha: alpha(0.3),
                coat_frame: Some(Frame::new(Vec3::new(0.3, 0.1, 1.0).normalize())),
                ..p
            },
        ),
        (
            "bent base",
            Principled { base_frame: Some(Frame::new(Vec3::new(0.15, -0.2, 1.0).normalize())), ..p },
        ),
        ("sheen", Principled { sheen: SheenLobe::new(Vec3::ONE, 0.4), sheen_roughness: 0.4, ..p }),
        ("smooth sheen", Principled { sheen: SheenLobe::new(Vec3::ONE, 0.0), sheen_roughness: 0.0, ..p }),
        ("specular colour", Principled { f0: Vec3::new(0.2, 0.04, 0.01), f90: 0.6, ..p }),
        ("transmission", Principled { transmission: 1.0, alpha: alpha(0.3), ..p }),
        ("thin transmission", Principled { transmission: 0.6, thin: true, alpha: alpha(0.4), ..p }),
        (
            "everything",
            Principled {
                metallic: 0.3,
                transmission: 0.5,
                coat: 0.5,
                sheen: SheenLobe::new(Vec3::splat(0.8), 0.6),
                sheen_roughness: 0.6,
                ..p
            },
        ),
    ]
}

/// The mean sample weight of `b` seen from `wo`, refraction counted at the radiance it carries
/// (without the 1 / eta^2 of crossing into the other medium), with its standard error, over
/// `n` samples.
fn albedo_of(b: &Principled, wo: Vec3, n: usize) -> (f64, f64) {
    let mut s = crate::render::sampler::Sampler::new(11, 7, 5);
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..n {
        let Some(bs) = b.sample(wo, &mut s) else { continue };
        let scale = match (bs.wi.z < 0.0 && !b.thin, b.entering) {
            (true, true) => b.ior * b.ior,
            (true, false) => 1.0 / (b.ior * b.ior),
            (false, _) => 1.0,
        };
        let w = (bs.weight.x * scale) as f64;
        sum += w;
        sum2 += w * w;
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(0.0);
    (mean, (var / n as f64).sqrt())
}

/// The furnace test of every layer: a white, non-absorbing layered material reflects and
/// transmits all the light at every view angle, within 4 standard errors and the accuracy of
/// the albedo tables (0.5%, the largest table error seen, at 85 degrees, 0.3%).
#[test]
fn white_layered_materials_keep_all_the_light() {
    let inside = Principled { transmission: 1.0, entering: false, alpha: alpha(0.2), ..principled() };
    // A rough, high index from inside: one facet alone loses up to a quarter of the light.
    let diamond = |roughness: f32| Principled { alpha: alpha(roughness), ior: 2.42, ..inside };
    let insides = [
        ("seen from inside", inside),
        ("rough diamond inside", diamond(0.5)),
        ("rougher diamond inside", diamond(1.0)),
    ];
    for (name, b) in layered_cases().into_iter().chain(insides) {
        if name == "specular colour" || name == "everything" {
            continue; // not white
        }
        let b = Principled { color: Vec3::ONE, ..b };
        for theta in [0.0, 30.0, 60.0, 75.0, 85.0] {
            let (albedo, error) = albedo_of(&b, wo(theta), 100_000);
            let tolerance = 4.0 * error + 0.005;
            if b.coat_frame.is_some() || b.base_frame.is_some() {
                // A coat or a base bent by its normal map reflects some light below the shading
                // normal's horizon, which is lost: it may keep less, never more (here at least
                // 97%: the coat reflects 4% to 30% of the light, and the base, tilted 14
                // degrees, loses (1 - cos 14) / 2 = 1.5% of what it reflects).
                assert!(
                    albedo < 1.0 + tolerance && albedo > 0.97,
                    "{name} at {theta} degrees: albedo {albedo} +- {error}"
                );
                continue;
            }
            assert!(
                (albedo - 1.0).abs() < tolerance,
                "{name} at {theta} degrees: albedo {albedo} +- {error}"
            );
        }
    }
}

/// Every layered case samples its reflecting lobes by their densities, through the interface
/// the integrator uses, and its transmitted directions by the transmission density.
#[test]
fn the_layered_bsdf_samples_its_density() {
    for (name, b) in layered_cases() {
        for theta in [20.0, 70.0] {
            check_through_the_interface(name, &b, wo(theta), Vec3::Z);
            if b.transmission > 0.0 {
                let wo = wo(theta);
                let z = z_score(
                    |s| b.sample(wo, s).map(|bs| bs.wi).filter(|d| d.z < 0.0),
                    |d| b.transmission_pdf(wo, d),
                );
                assert!(z < 4.0, "{name} transmission at {theta}: z = {z}");
            }
        }
    }
}

/// A white rough metal under the metallic-roughness BSDF reflects all the light (GGX's multiple
/// scattering restored), within 4 standard errors and the albedo table's accuracy (0.5%).
#[test]
fn a_white_rough_pbr_metal_keeps_all_the_light() {
    for roughness in [0.3, 0.6, 1.0] {
        let lobes = GlossyLobes { specular: Vec3::ONE, alpha: alpha(roughness), base: Vec3::ZERO };
        let metal = Pbr {
            lobes,
            base: Vec3::ZERO,
            frame: Frame::new(Vec3::Z),
            base_frame: None,
            rough: false,
            metallic: 1.0,
            metal: Vec3::ONE,
        };
        for theta in [0.0, 45.0, 80.0] {
            let mut s = crate::render::sampler::Sampler::new(2, 4, 6);
            let n = 100_000u64;
            let w: Vec<f64> =
                (0..n).map(|_| metal.sample(wo(theta), &mut s).map_or(0.0, |b| b.weight.x as f64)).collect();
            let mean = w.iter().sum::<f64>() / n as f64;
            let se = (w.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n * (n - 1)) as f64).sqrt();
            assert!(
                (mean - 1.0).abs() < 4.0 * se + 0.005,
                "roughness {roughness}, {theta} degrees: {mean} +- {se}"
            );
        }
    }
}

/// The albedo tables the renderer reads are the ones their integrators make, value for value
/// (to f32 rounding across compilers). With `LIGHTSPLIT_WRITE_TABLES=1` the test writes them
/// instead: after a change to a lobe or an integrator.
#[test]
fn the_stored_albedo_tables_are_their_integrals() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/render/bsdf/tables");
    let tables = [
        ("specular-albedo.bin", SpecularAlbedo::build().values(), SpecularAlbedo::get().values()),
        ("sheen-albedo.bin", sheen::SheenAlbedo::build().values(), sheen::SheenAlbedo::get().values()),
        ("inside-albedo.bin", InsideAlbedo::build().values(), InsideAlbedo::get().values()),
    ];
    for (file, built, stored) in tables {
        if std::env::var_os("LIGHTSPLIT_WRITE_TABLES").is_some() {
            let bytes: Vec<u8> = built.iter().flat_map(|v| v.to_le_bytes()).collect();
            std::fs::write(dir.join(file), bytes).expect("write the table");
            continue;
        }
        assert_eq!(built.len(), stored.len(), "{file}");
        let worst = built.iter().zip(&stored).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
        assert!(worst < 1e-5, "{file}: differs by {worst} from its integral");
    }
}

/// A plastic under test: its name, its material, its base colour.
type PlasticCase = (&'static str, crate::scene::PlasticMaterial, Vec3);

/// The Mitsuba BSDFs under test, as `scene::mitsuba` builds them: a GGX and an anisotropic
/// Beckmann rough conductor (the latter gold, from Mitsuba's table), a rough and a smooth
/// plastic, and two white rough conductors (eta 0, k 1: Mitsuba's `none`).
fn mitsuba_cases() -> (Vec<(&'static str, Conductor)>, Vec<PlasticCase>) {
    use super::microfacet::{Distribution, Microfacet};
    use crate::scene::{mitsuba::named_conductor, PlasticMaterial};
    let frame = Frame::new(Vec3::Z);
    let (au_eta, au_k) = named_conductor("Au").expect("gold is tabulated");
    let (none_eta, none_k) = named_conductor("none").expect("`none` is tabulated");
    let conductor = |eta, k, facets| Conductor { frame, eta, k, specular: Vec3::ONE, facets, rough: false };
    let conductors = vec![
        (
            "ggx_conductor",
            conductor(
                Vec3::new(0.2, 0.9, 1.1),
                Vec3::new(3.9, 2.4, 2.2),
                Some(Microfacet::new(Distribution::Ggx, 0.3, 0.3)),
            ),
        ),
        (
            "beckmann_anisotropic",
            conductor(au_eta, au_k, Some(Microfacet::new(Distribution::Beckmann, 0.1, 0.4))),
        ),
        ("white_rough_ggx", conductor(none_eta, none_k, Some(Microfacet::new(Distribution::Ggx, 0.5, 0.5)))),
        (
            "white_rough_beckmann",
            conductor(none_eta, none_k, Some(Microfacet::new(Distribution::Beckmann, 0.2, 0.6))),
        ),
    ];
    let rough = Some(Microfacet::new(Distribution::Ggx, 0.2, 0.2));
    let (d1, d2) = (Vec3::new(0.5, 0.3, 0.1), Vec3::new(0.2, 0.6, 0.4));
    let plastics = vec![
        ("rough_plastic", PlasticMaterial::new(1.5, d1, d1.element_sum() / 3.0, Vec3::ONE, false, rough), d1),
        ("smooth_plastic", PlasticMaterial::new(1.6, d2, d2.element_sum() / 3.0, Vec3::ONE, false, None), d2),
    ];
    (conductors, plastics)
}

/// A direction at polar angle `theta` and azimuth `phi`, in degrees.
fn polar(theta: f32, phi: f32) -> Vec3 {
    let (t, p) = (theta.to_radians(), phi.to_radians());
    Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}

/// The non-delta value f(wo, wi) cos(wi) of a BSDF, summed over its lobes.
fn f_cos<B: Bsdf>(b: &B, wo: Vec3, wi: Vec3) -> Vec3 {
    let mut sum = Vec3::ZERO;
    b.eval_lobes(wo, wi, |_, f, _| sum += f);
    sum * wi.z
}

/// Mitsuba 3's own `bsdf.eval` (scalar_rgb), computed by `scripts/mitsuba/bsdf_values.py`: for
/// each case, ((theta, phi) of the view, (theta, phi) of the light, f cos). lightsplit's values
/// agree within 1% (plus 1e-6): Mitsuba evaluates in single precision too, and its rough
/// coating's table is integrated differently (by its own quadrature; here over strata).
#[test]
fn mitsuba_bsdfs_agree_with_mitsubas_own_values() {
    type Row = ((f32, f32), (f32, f32), [f32; 3]);
    let values: &[(&str, [Row; 5])] = &[
        (
            "ggx_conductor",
            [
                ((10.0, 0.0), (15.0, 180.0), [8.20828e-01, 5.30974e-01, 4.52116e-01]),
                ((40.0, 30.0), (50.0, 200.0), [7.90113e-01, 5.12302e-01, 4.38649e-01]),
                ((70.0, 90.0), (20.0, 270.0), [2.70944e-01, 1.75691e-01, 1.50450e-01]),
                ((30.0, 0.0), (60.0, 100.0), [5.23001e-02, 3.38456e-02, 2.88715e-02]),
                ((5.0, 0.0), (80.0, 45.0), [1.87443e-02, 1.21350e-02, 1.03619e-02]),
            ],
        ),
        (
            "beckmann_anisotropic",
            [
                ((10.0, 0.0), (15.0, 180.0), [1.62003e+00, 1.34405e+00, 5.43287e-01]),
                ((40.0, 30.0), (50.0, 200.0), [6.68053e-01, 5.54273e-01, 2.32315e-01]),
                ((70.0, 90.0), (20.0, 270.0), [2.06319e+00, 1.71183e+00, 7.18031e-01]),
                ((30.0, 0.0), (60.0, 100.0), [5.87608e-04, 4.87380e-04, 1.99375e-04]),
                ((5.0, 0.0), (80.0, 45.0), [1.99705e-20, 1.65640e-20, 6.82008e-21]),
            ],
        ),
        (
            "rough_plastic",
            [
                ((10.0, 0.0), (15.0, 180.0), [1.95538e-01, 1.46842e-01, 9.81463e-02]),
                ((40.0, 30.0), (50.0, 200.0), [1.46516e-01, 1.15412e-01, 8.43074e-02]),
                ((70.0, 90.0), (20.0, 270.0), [1.13717e-01, 7.21276e-02, 3.05382e-02]),
                ((30.0, 0.0), (60.0, 100.0), [6.02526e-02, 3.66778e-02, 1.31030e-02]),
                ((5.0, 0.0), (80.0, 45.0), [1.76837e-02, 1.08177e-02, 3.95168e-03]),
            ],
        ),
        (
            "smooth_plastic",
            [
                ((10.0, 0.0), (15.0, 180.0), [6.17034e-02, 1.85110e-01, 1.23407e-01]),
                ((40.0, 30.0), (50.0, 200.0), [3.99697e-02, 1.19909e-01, 7.99393e-02]),
                ((70.0, 90.0), (20.0, 270.0), [5.14679e-02, 1.54404e-01, 1.02936e-01]),
                ((30.0, 0.0), (60.0, 100.0), [3.01360e-02, 9.04080e-02, 6.02720e-02]),
                ((5.0, 0.0), (80.0, 45.0), [7.00974e-03, 2.10292e-02, 1.40195e-02]),
            ],
        ),
    ];
    let (conductors, plastics) = mitsuba_cases();
    let frame = Frame::new(Vec3::Z);
    for (name, rows) in values {
        for &((t0, p0), (t1, p1), want) in rows {
            let (wo, wi) = (polar(t0, p0), polar(t1, p1));
            let got = match conductors.iter().find(|c| c.0 == *name) {
                Some((_, c)) => f_cos(c, wo, wi),
                None => {
                    let (_, m, d) = plastics.iter().find(|p| p.0 == *name).expect("a case of each name");
                    f_cos(&m.bsdf(*d, frame, false), wo, wi)
                }
            };
            let want = Vec3::from_array(want);
            let off = (got - want).abs() - (0.01 * want + Vec3::splat(1e-6));
            assert!(off.max_element() <= 0.0, "{name} at {wo} {wi}: {got} vs Mitsuba's {want}");
        }
    }
}

/// Mitsuba 3's own white furnaces of the white rough conductors (eta 0, k 1), from
/// `scripts/mitsuba/bsdf_values.py`: the mean sample weight and its standard error at view
/// angles 0, 45 and 80 degrees. Single scattering loses what bounces between the facets (GGX's
/// long tails the most: 31% at alpha 0.5); lightsplit must lose what Mitsuba loses.
const MITSUBA_FURNACES: &[(&str, [(f64, f64); 3])] = &[
    ("rough_glass", [(0.99486, 0.00021), (0.98656, 0.00028), (0.91344, 0.00060)]),
    ("white_rough_ggx", [(0.68824, 0.00123), (0.67923, 0.00119), (0.74581, 0.00096)]),
    ("white_rough_beckmann", [(0.94538, 0.00056), (0.92761, 0.00066), (0.87668, 0.00084)]),
];

/// Mitsuba's `roughdielectric` (GGX, alpha 0.2, index 1.5) seen from outside (`entering`) or
/// from inside (its normal then on the inside, toward the viewer).
fn rough_glass(entering: bool) -> RoughDielectric {
    use super::microfacet::{Distribution, Microfacet};
    RoughDielectric {
        frame: Frame::new(if entering { Vec3::Z } else { -Vec3::Z }),
        eta: 1.5,
        reflectance: Vec3::ONE,
        transmittance: Vec3::ONE,
        facets: Microfacet::new(Distribution::Ggx, 0.2, 0.2),
        entering,
        rough: false,
    }
}

/// A rough glass's f cos between world directions, reflected (through its lobes) or
/// transmitted.
fn glass_f_cos(b: &RoughDielectric, wo: Vec3, wi: Vec3) -> Vec3 {
    let n = b.frame.to_world(Vec3::Z);
    match n.dot(wi) > 0.0 {
        true => {
            let mut sum = Vec3::ZERO;
            b.eval_lobes(wo, wi, |_, f, _| sum += f);
            sum * n.dot(wi)
        }
        false => b.transmission(b.frame.to_local(wo), b.frame.to_local(wi)).0,
    }
}

/// The rough dielectric against Mitsuba's own `eval` from both sides, reflected and
/// transmitted (values from `scripts/mitsuba/bsdf_values.py`, within 1% plus 1e-6); its
/// sampling against its densities, above and through (chi-square); reciprocity of both lobes
/// (the transmission's up to its radiance scaling: eta^2 between the two ways through);
/// and its white furnace, light crossing counted back by eta^2, against Mitsuba's.
#[test]
fn the_rough_dielectric_is_mitsubas() {
    type Row = ((f32, f32), (f32, f32), f32);
    let rows: [(bool, [Row; 5]); 2] = [
        (
            true,
            [
                ((10.0, 0.0), (15.0, 180.0), 7.37984e-02),
                ((40.0, 30.0), (50.0, 200.0), 6.87552e-02),
                ((10.0, 0.0), (160.0, 180.0), 2.03135e-01),
                ((40.0, 30.0), (140.0, 200.0), 2.38823e-01),
                ((60.0, 90.0), (150.0, 260.0), 1.10542e+00),
            ],
        ),
        (
            false,
            [
                ((170.0, 0.0), (165.0, 180.0), 7.41187e-02),
                ((160.0, 30.0), (140.0, 200.0), 3.64703e-02),
                ((170.0, 0.0), (20.0, 180.0), 2.06195e+01),
                ((160.0, 30.0), (40.0, 200.0), 3.41676e+00),
                ((150.0, 90.0), (15.0, 260.0), 1.18498e-01),
            ],
        ),
    ];
    for (entering, rows) in rows {
        let b = rough_glass(entering);
        for ((t0, p0), (t1, p1), want) in rows {
            let got = glass_f_cos(&b, polar(t0, p0), polar(t1, p1)).x;
            assert!(
                (got - want).abs() <= 0.01 * want + 1e-6,
                "entering {entering}: {t0} {t1}: {got} vs Mitsuba's {want}"
            );
        }
    }
    for entering in [true, false] {
        let b = rough_glass(entering);
        let n = b.frame.to_world(Vec3::Z);
        for theta in [20.0f32, 70.0] {
            let wo = b.frame.to_world(polar(theta, 40.0));
            check_through_the_interface("rough glass", &b, wo, n);
            let z = z_score(
                |s| b.sample(wo, s).map(|bs| bs.wi).filter(|d| n.dot(*d) < 0.0),
                |d| b.transmission_pdf(wo, d),
            );
            assert!(z < 4.0, "rough glass through at {theta}, entering {entering}: z = {z}");
        }
    }
    let (outside, inside) = (rough_glass(true), rough_glass(false));
    let mut s = crate::render::sampler::Sampler::new(6, 6, 6);
    for _ in 0..2000 {
        let (a, c) = (cosine_hemisphere(s.next_2d()), cosine_hemisphere(s.next_2d()));
        let (ac, ca) = (glass_f_cos(&outside, a, c) / c.z, glass_f_cos(&outside, c, a) / a.z);
        assert!((ac - ca).abs().x <= 1e-3 * ac.x.max(1e-3), "reflection {a} {c}: {ac} vs {ca}");
        // Outside a, inside -c: radiance leaving the glass is eta^2 times what enters it, so
        // f(a -> -c) eta^2 = f(-c -> a).
        let below = -c;
        let there = glass_f_cos(&outside, a, below).x / c.z * 1.5 * 1.5;
        let back = glass_f_cos(&inside, below, a).x / a.z;
        assert!(
            (there - back).abs() <= 1e-3 * there.max(1e-3),
            "transmission {a} {below}: {there} vs {back}"
        );
    }
    let (_, theirs) = MITSUBA_FURNACES.iter().find(|f| f.0 == "rough_glass").expect("measured");
    for (k, theta) in [0.0f32, 45.0, 80.0].into_iter().enumerate() {
        let wo = polar(theta, 10.0);
        let mut s = crate::render::sampler::Sampler::new(2, 4, 8);
        let n = 100_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let w = outside.sample(wo, &mut s).map_or(0.0, |bs| match bs.wi.z < 0.0 {
                true => bs.weight.x as f64 * 1.5 * 1.5,
                false => bs.weight.x as f64,
            });
            sum += w;
            sum2 += w * w;
        }
        let mean = sum / n as f64;
        let e = ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
        let (m, me) = theirs[k];
        assert!(mean <= 1.0 + 4.0 * e, "rough glass at {theta}: {mean} +- {e}");
        assert!(
            (mean - m).abs() < 4.0 * e.hypot(me),
            "rough glass at {theta}: {mean} +- {e}, Mitsuba's {m} +- {me}"
        );
    }
}

/// The Mitsuba BSDFs sample their densities (chi-square through the integrator's interface),
/// are reciprocal (f(a, b) = f(b, a): the plastics' base term counts the coating's
/// transmittance both ways), and keep at most the light they receive: a white
/// conductor keeps all of it when smooth, and when rough what Mitsuba's keeps (single
/// scattering loses what bounces between facets); a plastic with a white base keeps at most
/// all of it.
#[test]
fn mitsuba_bsdfs_sample_their_density_are_reciprocal_and_keep_energy() {
    let (conductors, plastics) = mitsuba_cases();
    let frame = Frame::new(Vec3::Z);
    for theta in [20.0f32, 65.0] {
        let w = polar(theta, 30.0);
        for (name, c) in &conductors {
            check_through_the_interface(name, c, w, Vec3::Z);
        }
        for (name, m, d) in &plastics {
            check_through_the_interface(name, &m.bsdf(*d, frame, false), w, Vec3::Z);
        }
    }
    let mut s = crate::render::sampler::Sampler::new(8, 2, 3);
    for (name, c) in &conductors {
        for _ in 0..2000 {
            let (a, b) = (cosine_hemisphere(s.next_2d()), cosine_hemisphere(s.next_2d()));
            let (ab, ba) = (f_cos(c, a, b) / b.z, f_cos(c, b, a) / a.z);
            assert!(
                (ab - ba).abs().max_element() <= 1e-3 * ab.max_element().max(1e-3),
                "{name}: {a} {b}: {ab} vs {ba}"
            );
        }
    }
    for (name, m, d) in &plastics {
        let b = m.bsdf(*d, frame, false);
        for _ in 0..2000 {
            let (x, y) = (cosine_hemisphere(s.next_2d()), cosine_hemisphere(s.next_2d()));
            let (xy, yx) = (f_cos(&b, x, y) / y.z, f_cos(&b, y, x) / x.z);
            assert!(
                (xy - yx).abs().max_element() <= 1e-3 * xy.max_element().max(1e-3),
                "{name}: {x} {y}: {xy} vs {yx}"
            );
        }
    }
    // White furnaces: the mean sample weight, with its standard error.
    let albedo = |b: &dyn Fn(&mut crate::render::sampler::Sampler) -> Option<BsdfSample>| {
        let mut s = crate::render::sampler::Sampler::new(5, 9, 1);
        let n = 100_000;
        let (mut sum, mut sum2) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let w = b(&mut s).map_or(0.0, |bs| bs.weight.max_element() as f64);
            sum += w;
            sum2 += w * w;
        }
        let mean = sum / n as f64;
        (mean, ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt())
    };
    let (none_eta, none_k) = crate::scene::mitsuba::named_conductor("none").expect("tabulated");
    let mirror =
        Conductor { frame, eta: none_eta, k: none_k, specular: Vec3::ONE, facets: None, rough: false };
    for theta in [0.0f32, 45.0, 80.0] {
        let w = polar(theta, 10.0);
        let (a, _) = albedo(&|s| mirror.sample(w, s));
        assert!((a - 1.0).abs() < 1e-4, "white mirror at {theta}: {a}");
        for (name, c) in &conductors[2..] {
            let (a, e) = albedo(&|s| c.sample(w, s));
            let (_, theirs) = MITSUBA_FURNACES.iter().find(|f| f.0 == *name).expect("measured");
            let (m, me) = theirs[[0.0, 45.0, 80.0].iter().position(|t| *t == theta).expect("an angle")];
            assert!(a <= 1.0 + 4.0 * e, "{name} at {theta}: {a} +- {e}");
            assert!(
                (a - m).abs() < 4.0 * e.hypot(me),
                "{name} at {theta}: {a} +- {e}, Mitsuba's {m} +- {me}"
            );
        }
        for (name, m, _) in &plastics {
            let b = m.bsdf(Vec3::ONE, frame, false);
            let (a, e) = albedo(&|s| b.sample(w, s));
            assert!(a <= 1.0 + 4.0 * e + 0.01, "{name} at {theta}: {a} +- {e}");
        }
    }
}

/// Mitsuba's smooth `dielectric` and `thindielectric`, white: every sample keeps all the light
/// (refraction counted back by eta^2, a sheet's light passing straight through), and the share
/// reflected is the Fresnel reflectance (the sheet's, 2R / (1 + R), with its internal
/// bounces), within 4 binomial standard errors, from outside and from inside.
#[test]
fn white_smooth_dielectrics_keep_all_the_light_and_reflect_their_fresnel_share() {
    for (thin, entering) in [(false, true), (false, false), (true, true)] {
        let b = Dielectric {
            eta: 1.5,
            reflectance: Vec3::ONE,
            transmittance: Vec3::ONE,
            n: Vec3::Z,
            entering,
            thin,
        };
        for theta in [0.0f32, 30.0, 60.0, 85.0] {
            let wo = polar(theta, 20.0);
            let eta = if entering { 1.5f32 } else { 1.0 / 1.5 };
            let r = fresnel_dielectric(wo.z, if thin { 1.5 } else { eta });
            let want = if thin && r < 1.0 { 2.0 * r / (1.0 + r) } else { r };
            let mut s = crate::render::sampler::Sampler::new(9, 3, 1);
            let n = 20_000;
            let mut reflected = 0u32;
            for _ in 0..n {
                let bs = b.sample(wo, &mut s).expect("a smooth boundary always scatters");
                let through = bs.wi.z < 0.0;
                reflected += (!through) as u32;
                let kept = if through && !thin { bs.weight.x * eta * eta } else { bs.weight.x };
                assert!((kept - 1.0).abs() < 1e-5, "thin {thin}, entering {entering}, {theta}: {kept}");
                if thin && through {
                    assert!((bs.wi + wo).length() < 1e-6, "a sheet passes light straight through");
                }
            }
            let p = want as f64;
            let sigma = (p * (1.0 - p) / n as f64).sqrt().max(1e-4);
            let share = reflected as f64 / n as f64;
            assert!(
                (share - p).abs() < 4.0 * sigma,
                "thin {thin}, entering {entering}, {theta}: {share} vs {p}"
            );
        }
    }
}
