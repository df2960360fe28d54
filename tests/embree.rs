//! The Embree wrapper (`accel::embree`) against the library it was built for: here rather than
//! among the library's unit tests so that the Debian 13 run (Embree 4, `scripts/test-debian13.sh
//! --test integration`) reaches them.

use std::sync::Arc;

use glam::{Vec3, Vec3A, Vec4};
use lightsplit::accel::embree::{CommittedScene, Device};
use lightsplit::accel::{Hit, Ray};

fn triangle_scene() -> CommittedScene {
    let device = Device::new().expect("device");
    let mut scene = device.scene().expect("scene");
    let positions: Arc<[Vec3A]> =
        Arc::from(vec![Vec3A::new(0.0, 0.0, 0.0), Vec3A::new(1.0, 0.0, 0.0), Vec3A::new(0.0, 1.0, 0.0)]);
    let indices: Arc<[[u32; 3]]> = Arc::from(vec![[0u32, 1, 2]]);
    scene.add_triangles(3, positions, indices).expect("mesh");
    scene.add_spheres(5, &[Vec4::new(0.0, 0.0, 10.0, 2.0)]).expect("spheres");
    scene.commit().expect("commit")
}

#[test]
fn the_library_is_the_api_it_was_built_for() {
    let device = Device::new().expect("device");
    assert!(device.version() >= 31300);
    // 3 on Debian 12, 4 on Debian 13.
    assert_eq!(device.version() / 10000, embree_sys::API as i64);
}

#[test]
fn triangle_hit_has_expected_t_and_barycentrics() {
    let scene = triangle_scene();
    let hit = scene.intersect(&Ray::new(Vec3::new(0.25, 0.5, -2.0), Vec3::Z)).expect("hit");
    assert_eq!((hit.shape, hit.prim), (3, 0));
    assert!((hit.t - 2.0).abs() < 1e-6, "t = {}", hit.t);
    // p = (1-u-v) p0 + u p1 + v p2 = (u, v, 0)
    assert!((hit.u - 0.25).abs() < 1e-6 && (hit.v - 0.5).abs() < 1e-6, "{hit:?}");
}

#[test]
fn triangle_miss_and_t_max() {
    let scene = triangle_scene();
    assert!(scene.intersect(&Ray::new(Vec3::new(1.5, 1.5, -2.0), Vec3::Z)).is_none());
    let short = Ray { t_max: 1.5, ..Ray::new(Vec3::new(0.25, 0.25, -2.0), Vec3::Z) };
    assert!(scene.intersect(&short).is_none());
    assert!(!scene.occluded(&short));
    let long = Ray { t_max: 2.5, ..short };
    assert!(scene.occluded(&long));
}

#[test]
fn sphere_hit_from_outside_and_inside() {
    let scene = triangle_scene();
    let hit = scene.intersect(&Ray::new(Vec3::new(0.0, 0.0, 20.0), -Vec3::Z)).expect("hit");
    assert_eq!((hit.shape, hit.prim), (5, 0));
    assert!((hit.t - 8.0).abs() < 1e-5, "t = {}", hit.t);
    // From the centre the far side is 2 away.
    let inside = scene.intersect(&Ray::new(Vec3::new(0.0, 0.0, 10.0), Vec3::X)).expect("hit from inside");
    assert!((inside.t - 2.0).abs() < 1e-5, "t = {}", inside.t);
    assert!(scene.intersect(&Ray::new(Vec3::new(3.0, 0.0, 20.0), -Vec3::Z)).is_none());
}

#[test]
fn queries_from_many_threads_agree() {
    let scene = triangle_scene();
    let ray = |i: usize| Ray::new(Vec3::new((i % 40) as f32 / 40.0, (i / 40) as f32 / 25.0, -1.0), Vec3::Z);
    let expected: Vec<Option<Hit>> = (0..1000).map(|i| scene.intersect(&ray(i))).collect();
    assert!(expected.iter().filter(|h| h.is_some()).count() > 300);
    std::thread::scope(|s| {
        for _ in 0..4 {
            s.spawn(|| {
                for (i, want) in expected.iter().enumerate() {
                    assert_eq!(&scene.intersect(&ray(i)), want);
                }
            });
        }
    });
}

fn assert_send_sync<T: Send + Sync>() {}
#[test]
fn committed_scene_is_send_and_sync() {
    assert_send_sync::<CommittedScene>();
}
