//! The safe wrapper over Embree (3.13 or 4.x, chosen at build time as `cfg(embree4)`): the only
//! `unsafe` outside `sys/`. It owns device, scene and geometry lifetimes, turns Embree's error
//! callback into Rust errors, and separates a scene under construction ([`SceneBuilder`]) from a
//! committed one ([`CommittedScene`]): only the committed one is `Send + Sync`, because Embree
//! allows concurrent queries on a committed scene and nothing else.
#![allow(unsafe_code)]

use std::ffi::{c_char, c_void, CStr, CString};
use std::sync::{Arc, Mutex};

use embree_sys as sys;
use glam::{Vec3A, Vec4};

use super::{Accel, BuildHints, BuildQuality, Hit, Ray, PACKET};
use crate::scene::cutout::Cutouts;

/// `RTC_INVALID_GEOMETRY_ID` is a cast macro in the header, which bindgen cannot evaluate.
const INVALID_ID: u32 = u32::MAX;

/// An error reported by Embree, or by the wrapper about Embree.
#[derive(Debug, thiserror::Error)]
pub enum EmbreeError {
    #[error("Embree error {code}: {message}")]
    Api { code: u32, message: String },
    #[error("cannot create an Embree device: {0}")]
    Device(String),
    #[error("Embree library {library} does not match the header {header} it was built against")]
    Version { library: i64, header: i64 },
}

/// What the error callback writes: the first error since the last check.
type ErrorSlot = Mutex<Option<EmbreeError>>;

struct DeviceInner {
    raw: sys::RTCDevice,
    // Boxed so its address, handed to Embree as the callback's user pointer, never moves.
    errors: Box<ErrorSlot>,
}

// SAFETY: an RTCDevice may be used from any thread (Embree's device calls are thread-safe), and
// the error slot is behind a Mutex.
unsafe impl Send for DeviceInner {}
// SAFETY: as above: shared references only reach thread-safe Embree calls and the Mutex.
unsafe impl Sync for DeviceInner {}

impl Drop for DeviceInner {
    fn drop(&mut self) {
        // SAFETY: `raw` came from rtcNewDevice and this is the wrapper's only reference; every
        // scene holds an Arc<DeviceInner>, so none outlives this release.
        unsafe { sys::rtcReleaseDevice(self.raw) };
    }
}

impl DeviceInner {
    /// Takes the first error the callback recorded, if any.
    fn take_error(&self) -> Result<(), EmbreeError> {
        let mut slot = self.errors.lock().unwrap_or_else(|e| e.into_inner());
        match slot.take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

unsafe extern "C" fn error_callback(user: *mut c_void, code: sys::RTCError, message: *const c_char) {
    if user.is_null() {
        return;
    }
    // SAFETY: `user` is the address of the device's boxed ErrorSlot, registered in Device::new
    // and alive for as long as the device is; Embree passes a NUL-terminated message or null.
    let (slot, message) = unsafe {
        let slot = &*(user as *const ErrorSlot);
        let message = if message.is_null() {
            String::new()
        } else {
            CStr::from_ptr(message).to_string_lossy().into_owned()
        };
        (slot, message)
    };
    let mut slot = slot.lock().unwrap_or_else(|e| e.into_inner());
    if slot.is_none() {
        *slot = Some(EmbreeError::Api { code, message });
    }
}

/// An Embree device. Cheap to clone; scenes keep it alive.
#[derive(Clone)]
pub struct Device {
    inner: Arc<DeviceInner>,
}

impl Device {
    /// A device with Embree's default configuration.
    pub fn new() -> Result<Self, EmbreeError> {
        Self::with_config("")
    }

    /// A device with an Embree configuration string, e.g. `"threads=2"` (the build threads).
    pub fn with_config(config: &str) -> Result<Self, EmbreeError> {
        let config = CString::new(config)
            .map_err(|_| EmbreeError::Device("configuration contains a NUL byte".into()))?;
        // SAFETY: `config` is a valid NUL-terminated string that outlives the call.
        let raw = unsafe { sys::rtcNewDevice(config.as_ptr()) };
        if raw.is_null() {
            // SAFETY: rtcGetDeviceError accepts a null device and reports the creation error.
            let code = unsafe { sys::rtcGetDeviceError(std::ptr::null_mut()) };
            return Err(EmbreeError::Device(format!("rtcNewDevice failed with error {code}")));
        }
        let inner = Arc::new(DeviceInner { raw, errors: Box::new(Mutex::new(None)) });
        let user = &*inner.errors as *const ErrorSlot as *mut c_void;
        // SAFETY: `raw` is a live device; `user` points to the boxed slot owned by `inner`, which
        // lives until after rtcReleaseDevice in Drop.
        unsafe { sys::rtcSetDeviceErrorFunction(raw, Some(error_callback), user) };
        let device = Device { inner };
        device.check_version()?;
        Ok(device)
    }

    /// The header we were built against and the library we loaded must share a major version
    /// and the library must be at least as new as the header.
    fn check_version(&self) -> Result<(), EmbreeError> {
        // SAFETY: `raw` is a live device and the property is a plain integer query.
        let library =
            unsafe { sys::rtcGetDeviceProperty(self.inner.raw, sys::RTC_DEVICE_PROPERTY_VERSION) } as i64;
        let header = sys::RTC_VERSION as i64;
        if library / 10000 != header / 10000 || library < header / 100 * 100 {
            return Err(EmbreeError::Version { library, header });
        }
        Ok(())
    }

    /// The Embree version of the loaded library, as `major * 10000 + minor * 100 + patch`.
    pub fn version(&self) -> i64 {
        // SAFETY: `raw` is a live device and the property is a plain integer query.
        unsafe { sys::rtcGetDeviceProperty(self.inner.raw, sys::RTC_DEVICE_PROPERTY_VERSION) as i64 }
    }

    /// A new, empty scene to fill and commit: robust (watertight) and of high build quality.
    pub fn scene(&self) -> Result<SceneBuilder, EmbreeError> {
        self.scene_with(BuildHints::default())
    }

    /// A new, empty scene with these settings.
    pub fn scene_with(&self, settings: BuildHints) -> Result<SceneBuilder, EmbreeError> {
        // SAFETY: `raw` is a live device.
        let raw = unsafe { sys::rtcNewScene(self.inner.raw) };
        self.inner.take_error()?;
        if raw.is_null() {
            return Err(EmbreeError::Device("rtcNewScene returned null".into()));
        }
        let scene = SceneBuilder {
            raw,
            device: self.inner.clone(),
            meshes: Vec::new(),
            prototypes: Vec::new(),
            cutouts: None,
        };
        // SAFETY: `raw` is a live scene; these are plain setters.
        unsafe {
            let flags = if settings.robust { sys::RTC_SCENE_FLAG_ROBUST } else { sys::RTC_SCENE_FLAG_NONE };
            sys::rtcSetSceneFlags(raw, flags);
            sys::rtcSetSceneBuildQuality(raw, raw_quality(settings.quality));
        }
        self.inner.take_error()?;
        Ok(scene)
    }
}

/// Embree's build quality for a [`BuildQuality`].
fn raw_quality(quality: BuildQuality) -> sys::RTCBuildQuality {
    match quality {
        BuildQuality::Low => sys::RTC_BUILD_QUALITY_LOW,
        BuildQuality::Medium => sys::RTC_BUILD_QUALITY_MEDIUM,
        BuildQuality::High => sys::RTC_BUILD_QUALITY_HIGH,
    }
}

/// Triangle data shared with Embree without copying: kept alive for the scene's whole life.
struct SharedMesh {
    _positions: Arc<[Vec3A]>,
    _indices: Arc<[[u32; 3]]>,
}

/// A scene under construction. Not `Send` or `Sync`: Embree's build calls are not thread-safe on
/// one scene. [`SceneBuilder::commit`] consumes it and returns the queryable scene.
pub struct SceneBuilder {
    raw: sys::RTCScene,
    device: Arc<DeviceInner>,
    meshes: Vec<SharedMesh>,
    prototypes: Vec<Arc<CommittedScene>>,
    /// The cut-outs that the filter functions of its cut meshes read.
    cutouts: Option<Arc<Cutouts>>,
}

impl Drop for SceneBuilder {
    fn drop(&mut self) {
        if !self.raw.is_null() {
            // SAFETY: `raw` came from rtcNewScene and was not handed to a CommittedScene (commit
            // sets it to null).
            unsafe { sys::rtcReleaseScene(self.raw) };
        }
    }
}

impl SceneBuilder {
    fn attach(&mut self, geometry: sys::RTCGeometry, id: u32) -> Result<(), EmbreeError> {
        // SAFETY: `geometry` is a live geometry with its buffers set; the scene takes its own
        // reference on attach, so releasing ours afterwards is correct.
        unsafe {
            sys::rtcCommitGeometry(geometry);
            sys::rtcAttachGeometryByID(self.raw, geometry, id);
            sys::rtcReleaseGeometry(geometry);
        }
        self.device.take_error()
    }

    fn new_geometry(&self, kind: sys::RTCGeometryType) -> Result<sys::RTCGeometry, EmbreeError> {
        // SAFETY: the device is live; the type is one of the header's constants.
        let geometry = unsafe { sys::rtcNewGeometry(self.device.raw, kind) };
        self.device.take_error()?;
        if geometry.is_null() {
            return Err(EmbreeError::Device("rtcNewGeometry returned null".into()));
        }
        Ok(geometry)
    }

    /// Adds a triangle mesh with geometry ID `id`. The buffers are shared, not copied: Embree
    /// reads them in place for as long as the scene lives. Vertices are 16 bytes apart (`Vec3A`),
    /// which also gives Embree the readable padding it needs after the last vertex.
    pub fn add_triangles(
        &mut self,
        id: u32,
        positions: Arc<[Vec3A]>,
        indices: Arc<[[u32; 3]]>,
    ) -> Result<(), EmbreeError> {
        let geometry = self.mesh_geometry(positions, indices)?;
        self.attach(geometry, id)
    }

    /// [`Self::add_triangles`], its hits (camera and shadow rays alike) asked whether they count
    /// by `cutouts` ([`Cutouts::keeps`]) through Embree's intersection and occlusion filter
    /// functions: a mesh with a cut-out. A hit in an instance of this scene is asked about as
    /// the instance's geometry ID.
    pub fn add_cut_triangles(
        &mut self,
        id: u32,
        positions: Arc<[Vec3A]>,
        indices: Arc<[[u32; 3]]>,
        cutouts: &Arc<Cutouts>,
    ) -> Result<(), EmbreeError> {
        let cutouts = self.cutouts.get_or_insert_with(|| cutouts.clone()).clone();
        let geometry = self.mesh_geometry(positions, indices)?;
        // SAFETY: `geometry` is live and not yet committed. The user pointer is the Cutouts the
        // builder (and then the committed scene) holds in an Arc, alive for as long as Embree
        // may call the filters; `cutout_filter` only reads through it.
        unsafe {
            sys::rtcSetGeometryUserData(geometry, Arc::as_ptr(&cutouts) as *mut c_void);
            sys::rtcSetGeometryIntersectFilterFunction(geometry, Some(cutout_filter));
            sys::rtcSetGeometryOccludedFilterFunction(geometry, Some(cutout_filter));
        }
        self.attach(geometry, id)
    }

    /// A triangle geometry reading these buffers in place (kept alive by `self.meshes`), not
    /// yet attached.
    fn mesh_geometry(
        &mut self,
        positions: Arc<[Vec3A]>,
        indices: Arc<[[u32; 3]]>,
    ) -> Result<sys::RTCGeometry, EmbreeError> {
        const _: () = assert!(std::mem::size_of::<Vec3A>() == 16);
        let geometry = self.new_geometry(sys::RTC_GEOMETRY_TYPE_TRIANGLE)?;
        // SAFETY: both pointers stay valid (the Arcs are stored in `self.meshes` and moved into
        // the committed scene); strides and counts describe the slices exactly; Vec3A is 16-byte
        // aligned and [u32; 3] 4-byte aligned, as Embree requires.
        unsafe {
            sys::rtcSetSharedGeometryBuffer(
                geometry,
                sys::RTC_BUFFER_TYPE_VERTEX,
                0,
                sys::RTC_FORMAT_FLOAT3,
                positions.as_ptr() as *const c_void,
                0,
                16,
                positions.len(),
            );
            sys::rtcSetSharedGeometryBuffer(
                geometry,
                sys::RTC_BUFFER_TYPE_INDEX,
                0,
                sys::RTC_FORMAT_UINT3,
                indices.as_ptr() as *const c_void,
                0,
                12,
                indices.len(),
            );
        }
        self.meshes.push(SharedMesh { _positions: positions, _indices: indices });
        Ok(geometry)
    }

    /// Adds analytic spheres (`RTC_GEOMETRY_TYPE_SPHERE_POINT`) with geometry ID `id`; each
    /// sphere is `(x, y, z, radius)` and its primitive index is its place in `spheres`.
    pub fn add_spheres(&mut self, id: u32, spheres: &[Vec4]) -> Result<(), EmbreeError> {
        let geometry = self.new_geometry(sys::RTC_GEOMETRY_TYPE_SPHERE_POINT)?;
        // SAFETY: Embree allocates a buffer of `spheres.len()` FLOAT4 items (with its own padding)
        // and returns it; we write exactly that many items before committing.
        unsafe {
            let buffer = sys::rtcSetNewGeometryBuffer(
                geometry,
                sys::RTC_BUFFER_TYPE_VERTEX,
                0,
                sys::RTC_FORMAT_FLOAT4,
                16,
                spheres.len(),
            ) as *mut [f32; 4];
            if buffer.is_null() {
                sys::rtcReleaseGeometry(geometry);
                self.device.take_error()?;
                return Err(EmbreeError::Device("rtcSetNewGeometryBuffer returned null".into()));
            }
            for (i, s) in spheres.iter().enumerate() {
                buffer.add(i).write(s.to_array());
            }
        }
        self.attach(geometry, id)
    }

    /// Adds an instance of `prototype` (a committed scene of the same device) with geometry ID
    /// `id`, placed by `to_world`. Its hits report `id` as their shape (the instance's ID, not
    /// the geometry's within the prototype) and the prototype's primitive index.
    pub fn add_instance(
        &mut self,
        id: u32,
        prototype: &Arc<CommittedScene>,
        to_world: glam::Affine3A,
    ) -> Result<(), EmbreeError> {
        if !Arc::ptr_eq(&prototype._device, &self.device) {
            return Err(EmbreeError::Device("an instance of a scene of another device".into()));
        }
        let geometry = self.new_geometry(sys::RTC_GEOMETRY_TYPE_INSTANCE)?;
        // Column-major 3x4: the linear part's columns, then the translation.
        let m = to_world.matrix3;
        let t = to_world.translation;
        let columns: [f32; 12] = [
            m.x_axis.x, m.x_axis.y, m.x_axis.z, m.y_axis.x, m.y_axis.y, m.y_axis.z, m.z_axis.x, m.z_axis.y,
            m.z_axis.z, t.x, t.y, t.z,
        ];
        // SAFETY: `geometry` is a live instance geometry; the prototype is a committed scene of
        // this device, kept alive by `self.prototypes` (and the committed scene after) for as
        // long as this scene lives; Embree copies the 12 floats of the transform, which are
        // read from a live local array in the format named.
        unsafe {
            sys::rtcSetGeometryInstancedScene(geometry, prototype.raw);
            sys::rtcSetGeometryTimeStepCount(geometry, 1);
            sys::rtcSetGeometryTransform(
                geometry,
                0,
                sys::RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR,
                columns.as_ptr() as *const c_void,
            );
        }
        self.prototypes.push(prototype.clone());
        self.attach(geometry, id)
    }

    /// Builds the BVH and returns the scene, now immutable and shareable across threads.
    pub fn commit(mut self) -> Result<CommittedScene, EmbreeError> {
        // SAFETY: `raw` is a live scene with all geometry attached.
        unsafe { sys::rtcCommitScene(self.raw) };
        self.device.take_error()?;
        let raw = std::mem::replace(&mut self.raw, std::ptr::null_mut());
        // SAFETY: a plain integer query on a live device.
        let native8 = unsafe {
            sys::rtcGetDeviceProperty(self.device.raw, sys::RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED)
        };
        Ok(CommittedScene {
            raw,
            packets: native8 != 0,
            _device: self.device.clone(),
            _meshes: std::mem::take(&mut self.meshes),
            _prototypes: std::mem::take(&mut self.prototypes),
            _cutouts: self.cutouts.take(),
        })
    }
}

/// A committed scene: immutable, queried from any number of threads at once.
pub struct CommittedScene {
    raw: sys::RTCScene,
    /// Whether this Embree traces 8-ray packets natively (compiled with packets, and an ISA with
    /// 8-wide SIMD); without, coherent rays go one at a time with the coherent flag.
    packets: bool,
    _device: Arc<DeviceInner>,
    _meshes: Vec<SharedMesh>,
    /// The scenes this one instances.
    _prototypes: Vec<Arc<CommittedScene>>,
    /// What the filter functions of its cut meshes read.
    _cutouts: Option<Arc<Cutouts>>,
}

/// The intersection and occlusion filter of a mesh with a cut-out: each valid hit of the
/// packet that [`Cutouts::keeps`] refuses is made invalid, so Embree goes on past it.
unsafe extern "C" fn cutout_filter(args: *const sys::RTCFilterFunctionNArguments) {
    // SAFETY: Embree passes valid arguments: `valid` holds N ints, `hit` is an RTCHitN of N
    // lanes laid out as the header's RTCHitN_* accessors read it (Ng x, y, z, u, v, primID,
    // geomID, then instID of each level, N floats or uints each), and the user pointer is the
    // Cutouts `add_cut_triangles` set, alive as long as the scene is.
    unsafe {
        let args = &*args;
        let n = args.N as usize;
        if args.valid.is_null() || args.hit.is_null() || args.geometryUserPtr.is_null() {
            return;
        }
        let cutouts = &*(args.geometryUserPtr as *const Cutouts);
        let valid = std::slice::from_raw_parts_mut(args.valid, n);
        let floats = args.hit as *const f32;
        let words = args.hit as *const u32;
        for (i, valid) in valid.iter_mut().enumerate() {
            if *valid == 0 {
                continue;
            }
            let (u, v) = (*floats.add(3 * n + i), *floats.add(4 * n + i));
            let (prim, geometry, instance) =
                (*words.add(5 * n + i), *words.add(6 * n + i), *words.add(7 * n + i));
            if !cutouts.keeps(shape_of(instance, geometry), prim, u, v) {
                *valid = 0;
            }
        }
    }
}

// SAFETY: a committed Embree scene is never modified again (no method takes &mut or rebuilds it),
// and Embree documents rtcIntersect1/rtcOccluded1 on a committed scene as thread-safe.
unsafe impl Send for CommittedScene {}
// SAFETY: as above; shared references only reach the thread-safe query functions.
unsafe impl Sync for CommittedScene {}

impl Drop for CommittedScene {
    fn drop(&mut self) {
        // SAFETY: `raw` is the scene handed over by commit, released exactly once here.
        unsafe { sys::rtcReleaseScene(self.raw) };
    }
}

/// The shape of a hit: the instance's geometry ID when the hit is inside one, else the
/// geometry's.
#[inline(always)]
fn shape_of(instance: u32, geometry: u32) -> u32 {
    if instance != INVALID_ID {
        instance
    } else {
        geometry
    }
}

fn ray_to_sys(ray: &Ray) -> sys::RTCRay {
    sys::RTCRay {
        org_x: ray.origin.x,
        org_y: ray.origin.y,
        org_z: ray.origin.z,
        tnear: 0.0,
        dir_x: ray.dir.x,
        dir_y: ray.dir.y,
        dir_z: ray.dir.z,
        time: 0.0,
        tfar: ray.t_max,
        // Embree 4 masks rays by default: a zero mask would miss everything.
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}

impl CommittedScene {
    /// The closest hit along `ray`.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_one(ray, Coherence::Incoherent)
    }

    /// The closest hits of `rays`, which start together and point nearly the same way (the
    /// camera rays of one pixel): traced as 8-ray packets with the coherent flag where Embree
    /// has native 8-wide packets, else one by one with the coherent flag. `hits[i]` is the hit
    /// of `rays[i]`.
    pub fn intersect_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        debug_assert_eq!(rays.len(), hits.len());
        if !self.packets {
            for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
                *hit = self.intersect_one(ray, Coherence::Coherent);
            }
            return;
        }
        for (rays, hits) in rays.chunks(PACKET).zip(hits.chunks_mut(PACKET)) {
            let mut valid = Valid8([0; PACKET]);
            let mut packet = sys::RTCRayHit8::default();
            let (r, h) = (&mut packet.ray, &mut packet.hit);
            for (j, ray) in rays.iter().enumerate() {
                valid.0[j] = -1;
                (r.org_x[j], r.org_y[j], r.org_z[j]) = (ray.origin.x, ray.origin.y, ray.origin.z);
                (r.dir_x[j], r.dir_y[j], r.dir_z[j]) = (ray.dir.x, ray.dir.y, ray.dir.z);
                r.tfar[j] = ray.t_max;
                r.mask[j] = u32::MAX;
                h.geomID[j] = INVALID_ID;
                h.primID[j] = INVALID_ID;
                for level in h.instID.iter_mut() {
                    level[j] = INVALID_ID;
                }
            }
            intersect8(self.raw, &valid, &mut packet);
            let h = &packet.hit;
            for (j, hit) in hits.iter_mut().enumerate() {
                *hit = (h.geomID[j] != INVALID_ID).then_some(Hit {
                    t: packet.ray.tfar[j],
                    shape: shape_of(h.instID[0][j], h.geomID[j]),
                    prim: h.primID[j],
                    u: h.u[j],
                    v: h.v[j],
                });
            }
        }
    }

    fn intersect_one(&self, ray: &Ray, coherence: Coherence) -> Option<Hit> {
        let mut rayhit = sys::RTCRayHit {
            ray: ray_to_sys(ray),
            hit: sys::RTCHit {
                geomID: INVALID_ID,
                primID: INVALID_ID,
                instID: [INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
                ..Default::default()
            },
        };
        intersect1(self.raw, &mut rayhit, coherence);
        (rayhit.hit.geomID != INVALID_ID).then_some(Hit {
            t: rayhit.ray.tfar,
            shape: shape_of(rayhit.hit.instID[0], rayhit.hit.geomID),
            prim: rayhit.hit.primID,
            u: rayhit.hit.u,
            v: rayhit.hit.v,
        })
    }

    /// Whether anything blocks `ray` within `[0, ray.t_max]`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let mut sys_ray = ray_to_sys(ray);
        occluded1(self.raw, &mut sys_ray);
        // Embree marks an occluded ray by setting tfar to -inf.
        sys_ray.tfar == f32::NEG_INFINITY
    }
}

impl Accel for CommittedScene {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        CommittedScene::intersect(self, ray)
    }

    fn intersect_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        CommittedScene::intersect_coherent(self, rays, hits)
    }

    fn occluded(&self, ray: &Ray) -> bool {
        CommittedScene::occluded(self, ray)
    }
}

/// An 8-ray packet's valid mask, aligned to 32 bytes as `rtcIntersect8` requires: Embree's
/// AVX-512 kernels load it with an aligned move, which faults on a 16-byte aligned array (its
/// AVX2 kernels happened not to).
#[repr(C, align(32))]
struct Valid8([i32; PACKET]);

/// Embree's hint of how rays traced together relate: camera rays of one pixel are coherent,
/// bounce and shadow rays are not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Coherence {
    Coherent,
    Incoherent,
}

// The functions where Embree 3 and 4 differ: Embree 3 passes an RTCIntersectContext (initialised
// by the header-inline rtcInitIntersectContext, written here in Rust), Embree 4 an optional
// RTCIntersectArguments / RTCOccludedArguments after the ray.

#[cfg(not(embree4))]
// Embree 3 headers built with more instance levels add fields; default those.
#[allow(clippy::needless_update)]
fn context(coherence: Coherence) -> sys::RTCIntersectContext {
    sys::RTCIntersectContext {
        flags: match coherence {
            Coherence::Coherent => sys::RTC_INTERSECT_CONTEXT_FLAG_COHERENT,
            Coherence::Incoherent => sys::RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT,
        },
        filter: None,
        instID: [INVALID_ID; sys::RTC_MAX_INSTANCE_LEVEL_COUNT as usize],
        ..Default::default()
    }
}

#[cfg(not(embree4))]
fn intersect1(scene: sys::RTCScene, rayhit: &mut sys::RTCRayHit, coherence: Coherence) {
    let mut ctx = context(coherence);
    // SAFETY: `scene` is a live committed scene; `ctx` and `rayhit` are valid for the call and
    // `rayhit` is 16-byte aligned (RTCRayHit carries align(16)).
    unsafe { sys::rtcIntersect1(scene, &mut ctx, rayhit) }
}

#[cfg(not(embree4))]
fn intersect8(scene: sys::RTCScene, valid: &Valid8, packet: &mut sys::RTCRayHit8) {
    let mut ctx = context(Coherence::Coherent);
    // SAFETY: `scene` is a live committed scene; `valid` holds 8 ints aligned to 32 bytes
    // (`Valid8`), `packet` is an 8-ray packet aligned to 32 bytes (RTCRayHit8 carries
    // align(32)), both valid for the call.
    unsafe { sys::rtcIntersect8(valid.0.as_ptr(), scene, &mut ctx, packet) }
}

#[cfg(not(embree4))]
fn occluded1(scene: sys::RTCScene, ray: &mut sys::RTCRay) {
    let mut ctx = context(Coherence::Incoherent);
    // SAFETY: `scene` is a live committed scene; `ctx` and `ray` are valid for the call and `ray`
    // is 16-byte aligned.
    unsafe { sys::rtcOccluded1(scene, &mut ctx, ray) }
}

#[cfg(embree4)]
fn arguments(coherence: Coherence) -> sys::RTCIntersectArguments {
    // rtcInitIntersectArguments, which is header-inline.
    sys::RTCIntersectArguments {
        flags: match coherence {
            Coherence::Coherent => sys::RTC_RAY_QUERY_FLAG_COHERENT,
            Coherence::Incoherent => sys::RTC_RAY_QUERY_FLAG_INCOHERENT,
        },
        feature_mask: sys::RTC_FEATURE_FLAG_ALL,
        ..Default::default()
    }
}

#[cfg(embree4)]
fn intersect1(scene: sys::RTCScene, rayhit: &mut sys::RTCRayHit, coherence: Coherence) {
    let mut args = arguments(coherence);
    // SAFETY: `scene` is a live committed scene; `rayhit` and `args` are valid for the call and
    // `rayhit` is 16-byte aligned.
    unsafe { sys::rtcIntersect1(scene, rayhit, &mut args) }
}

#[cfg(embree4)]
fn intersect8(scene: sys::RTCScene, valid: &Valid8, packet: &mut sys::RTCRayHit8) {
    let mut args = arguments(Coherence::Coherent);
    // SAFETY: `scene` is a live committed scene; `valid` holds 8 ints aligned to 32 bytes
    // (`Valid8`), `packet` is an 8-ray packet aligned to 32 bytes (RTCRayHit8 carries
    // align(32)); all are valid for the call.
    unsafe { sys::rtcIntersect8(valid.0.as_ptr(), scene, packet, &mut args) }
}

#[cfg(embree4)]
fn occluded1(scene: sys::RTCScene, ray: &mut sys::RTCRay) {
    // rtcInitOccludedArguments, which is header-inline.
    let mut args = sys::RTCOccludedArguments {
        flags: sys::RTC_RAY_QUERY_FLAG_INCOHERENT,
        feature_mask: sys::RTC_FEATURE_FLAG_ALL,
        ..Default::default()
    };
    // SAFETY: `scene` is a live committed scene; `ray` and `args` are valid for the call and
    // `ray` is 16-byte aligned.
    unsafe { sys::rtcOccluded1(scene, ray, &mut args) }
}

#[cfg(test)]
mod tests {
    use super::*;

    // The wrapper's other tests are in tests/embree.rs, where the Debian 13 run (Embree 4)
    // reaches them without building the library's unit tests a second time.
    #[test]
    fn device_errors_become_rust_errors() {
        let device = Device::new().expect("device");
        // An unknown geometry type is an Embree error, reported through the callback.
        let scene = device.scene().expect("scene");
        let err = scene.new_geometry(9999).expect_err("an unknown type must fail");
        assert!(matches!(err, EmbreeError::Api { .. }), "{err}");
    }
}
