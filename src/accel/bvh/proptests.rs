//! Property tests of the BVH's ray/box and ray/triangle code against a float64 reference, and
//! of watertightness: random boxes, triangles and rays, each judged where f64 is unambiguous.

use glam::{DVec3, Vec3};
use proptest::prelude::*;

use super::simd::{BoxTest, Isa, Portable, RayBox8};
use super::tests::{mesh, scene_of};
use super::wide::Node8;
use super::*;

/// The slab test in f64: the parameter interval where the ray is inside the box, if any.
fn slab_f64(o: DVec3, d: DVec3, min: DVec3, max: DVec3) -> Option<(f64, f64)> {
    let (mut near, mut far) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if d[a] == 0.0 {
            if o[a] < min[a] || o[a] > max[a] {
                return None;
            }
            continue;
        }
        let (t0, t1) = ((min[a] - o[a]) / d[a], (max[a] - o[a]) / d[a]);
        near = near.max(t0.min(t1));
        far = far.min(t0.max(t1));
    }
    (near <= far).then_some((near, far))
}

/// Möller–Trumbore in f64: `(t, u, v)` of the plane hit, whatever the signs.
fn triangle_f64(o: DVec3, d: DVec3, v: [DVec3; 3]) -> Option<(f64, f64, f64)> {
    let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
    let p = d.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let s = o - v[0];
    let u = s.dot(p) / det;
    let q = s.cross(e1);
    let w = d.dot(q) / det;
    Some((e2.dot(q) / det, u, w))
}

fn coord() -> impl Strategy<Value = f32> {
    -10.0f32..10.0
}

fn point() -> impl Strategy<Value = Vec3> {
    (coord(), coord(), coord()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}

fn ray_of(o: Vec3, d: Vec3) -> Ray {
    Ray { origin: o, dir: d, t_max: f32::INFINITY }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, max_global_rejects: 20_000, ..ProptestConfig::default() })]

    /// The box tests never miss a box the ray enters (in f64, with any overlap at all), and
    /// never report one it clearly passes.
    #[test]
    fn box_tests_agree_with_f64(a in point(), b in point(), o in point(), d in point()) {
        prop_assume!(d.length() > 1e-3);
        let (min, max) = (a.min(b), a.max(b));
        let reference = slab_f64(o.as_dvec3(), d.as_dvec3(), min.as_dvec3(), max.as_dvec3());
        let ray = ray_of(o, d);
        let node = Node { min: min.to_array(), first: 0, max: max.to_array(), count: 1 };
        let binary = RayBox::new(&ray).hit(&node, f32::INFINITY).is_some();
        let (node8, rb) = (Node8::with_first_box(min, max), RayBox8::new(&ray));
        let portable = Portable.hit(&rb, &node8, f32::INFINITY).1 & 1 != 0;
        // The kernel this CPU runs (AVX2 on x86-64 machines that have it).
        let wide = Isa::best().hit(&rb, &node8, f32::INFINITY).1 & 1 != 0;
        prop_assert_eq!(portable, wide);
        match reference {
            Some((near, far)) if far >= near => {
                prop_assert!(binary && wide, "missed: enters at {near}, leaves at {far}");
            }
            _ => {}
        }
        // A clear miss: even the box grown by 1e-4 of the scene is missed.
        let grown = slab_f64(o.as_dvec3(), d.as_dvec3(), min.as_dvec3() - 2e-3, max.as_dvec3() + 2e-3);
        if grown.is_none() {
            prop_assert!(!binary && !wide, "reported a box the ray passes");
        }
    }

    /// Triangles: where f64 puts the hit clearly inside (every barycentric above 1e-4) at a
    /// clear angle, both the BVH's trees hit it with t and (u, v) close to f64's; where f64
    /// puts it clearly outside, they miss.
    #[test]
    fn triangle_tests_agree_with_f64(v0 in point(), v1 in point(), v2 in point(), o in point(),
                                     u in -0.5f32..1.5, w in -0.5f32..1.5) {
        let n = (v1 - v0).cross(v2 - v0);
        let longest = (v1 - v0).length().max((v2 - v0).length()).max((v2 - v1).length());
        // Well-shaped: twice the area at least a hundredth of the longest edge squared.
        prop_assume!(n.length() > 1e-2 * longest * longest && longest > 1e-2);
        let target = v0 * (1.0 - u - w) + v1 * u + v2 * w;
        let d = target - o;
        prop_assume!(d.length() > 1e-2 && n.normalize().dot(d.normalize()).abs() > 0.05);
        let Some((t, ru, rw)) = triangle_f64(o.as_dvec3(), d.as_dvec3(), [v0, v1, v2].map(|p| p.as_dvec3()))
        else { return Ok(()) };
        let scene = scene_of(vec![mesh(vec![v0, v1, v2], vec![[0, 1, 2]])]);
        let bvh = Bvh::with_reference(&scene).expect("builds");
        let ray = ray_of(o, d);
        let margin = 1e-4;
        let inside = ru > margin && rw > margin && 1.0 - ru - rw > margin && t > margin;
        let outside = ru < -margin || rw < -margin || 1.0 - ru - rw < -margin || t < -margin;
        for hit in [bvh.intersect(&ray), bvh.intersect_binary(&ray)] {
            if inside {
                let h = hit.ok_or_else(|| TestCaseError::fail(format!("missed at t {t}, ({ru}, {rw})")))?;
                prop_assert!((h.t as f64 - t).abs() < 1e-4 * t.max(1.0), "t {} vs {t}", h.t);
                prop_assert!((h.u as f64 - ru).abs() < 1e-3 && (h.v as f64 - rw).abs() < 1e-3,
                             "({}, {}) vs ({ru}, {rw})", h.u, h.v);
            } else if outside {
                prop_assert!(hit.is_none(), "hit {hit:?}, f64 says t {t}, ({ru}, {rw})");
            }
        }
        prop_assert_eq!(bvh.occluded(&ray), bvh.intersect(&ray).is_some());
    }

    /// Watertightness: a ray aimed at a point of the edge two triangles share (f32 vertices, the
    /// point rounded to f32, so on either side of the edge or on it) hits one of them.
    #[test]
    fn no_ray_slips_between_two_triangles(a in point(), b in point(), c in point(), e in point(),
                                           o in point(), s in 1e-3f32..0.999) {
        let (n1, n2) = ((b - a).cross(c - a), (e - a).cross(b - a));
        prop_assume!(n1.length() > 1e-2 && n2.length() > 1e-2);
        // Triangles (a, b, c) and (a, e, b) share the edge a-b, wound alike.
        let scene = scene_of(vec![mesh(vec![a, b, c, e], vec![[0, 1, 2], [0, 3, 1]])]);
        for (kind, bvh) in Bvh::both_kinds(&scene) {
            let target = a + (b - a) * s;
            let d = target - o;
            prop_assume!(d.length() > 1e-2);
            // Both seen from the same side, so that around the edge the ray sees one surface
            // (a fold seen from its back shows both triangles on one side of the edge, and a ray
            // beside it rightly misses both); and not along either plane.
            let (c1, c2) = (n1.normalize().dot(d.normalize()), n2.normalize().dot(d.normalize()));
            prop_assume!(c1 * c2 > 0.0 && c1.abs() > 1e-3 && c2.abs() > 1e-3);
            let ray = ray_of(o, d);
            prop_assert!(bvh.intersect(&ray).is_some() && bvh.intersect_binary(&ray).is_some(),
                         "{kind}: slipped through at {target}");
        }
    }

    /// A ray aimed exactly at the apex of a closed fan of triangles (the apex seen inside the
    /// fan's outline), in any orientation, hits the fan.
    #[test]
    fn no_ray_slips_through_a_vertex(apex_z in -1.0f32..1.0, radii in prop::array::uniform5(0.5f32..3.0),
                                     heights in prop::array::uniform5(-1.0f32..1.0),
                                     jitter in prop::array::uniform5(-0.3f32..0.3),
                                     lateral in (-0.4f32..0.4, -0.4f32..0.4),
                                     angles in (0.0f32..6.3, 0.0f32..6.3, 0.0f32..6.3),
                                     shift in point()) {
        let rotation = glam::Quat::from_euler(glam::EulerRot::XYZ, angles.0, angles.1, angles.2);
        let place = |p: Vec3| rotation * p + shift;
        let apex = place(Vec3::new(0.0, 0.0, apex_z));
        let ring: Vec<Vec3> = (0..5)
            .map(|k| {
                let theta = (k as f32 + jitter[k]) * std::f32::consts::TAU / 5.0;
                place(Vec3::new(radii[k] * theta.cos(), radii[k] * theta.sin(), heights[k]))
            })
            .collect();
        let mut positions = vec![apex];
        positions.extend(&ring);
        let indices: Vec<[u32; 3]> = (0..5u32).map(|k| [0, 1 + k, 1 + (k + 1) % 5]).collect();
        let scene = scene_of(vec![mesh(positions, indices)]);
        let origin = place(Vec3::new(lateral.0, lateral.1, 10.0));
        let ray = ray_of(origin, apex - origin);
        for (kind, bvh) in Bvh::both_kinds(&scene) {
            prop_assert!(bvh.intersect(&ray).is_some() && bvh.intersect_binary(&ray).is_some() && bvh.occluded(&ray),
                         "{kind}: slipped through the apex");
        }
    }
}
