//! Device-level tests on lavapipe (validation on when installed): rasterized G-buffer and ray
//! queries against CPU ray casting, forced staging, reflection, device selection, timestamps.

mod common;

use glam::Vec3;
use relit_engine::cpu;
use relit_engine::gpu::shaders;
use relit_engine::gpu::{
    self, vk, Buffer, DeviceChoice, Gpu, GpuOptions, MemoryLocation, Pipeline, RayScene, Timer,
};
use relit_engine::raster::GbufferPass;
use relit_engine::scene::synth::{self, Rng, SynthOptions};
use relit_engine::scene::Mesh;
use relit_engine::trace::{Ray, RayCaster};

/// The procedural room plus a soup of randomly oriented triangles (not axis-aligned, varied
/// sizes) so that hits are not all on grid-aligned quads.
fn test_mesh() -> Mesh {
    let (mut mesh, _) = synth::room(3);
    let mut rng = Rng::new(42);
    let mut soup = Mesh::default();
    for i in 0..120u32 {
        let c = Vec3::new(
            rng.range(-1.7, 1.7),
            rng.range(0.2, 2.4),
            rng.range(-1.5, 1.5),
        );
        let s = rng.range(0.05, 0.35);
        for _ in 0..3 {
            let p = c + Vec3::new(rng.range(-s, s), rng.range(-s, s), rng.range(-s, s));
            soup.positions.push(p.into());
        }
        soup.triangles.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    mesh.append(&soup);
    mesh
}

#[test]
fn gbuffer_matches_cpu_ray_cast() {
    let gpu = common::gpu();
    let mesh = test_mesh();
    let scene = RayScene::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let pass = GbufferPass::new(&gpu).unwrap();
    let cams = synth::capture_cameras(&SynthOptions {
        views: 3,
        width: 64,
        height: 48,
        ..Default::default()
    });
    for cam in &cams {
        let (near, far) = (0.05, 50.0);
        let g = pass.render(&scene, cam, near, far).unwrap();
        let px = g.download().unwrap();
        let (pos, nrm, tri) = (px.pos_depth, px.normal, px.tri);
        let r = cpu::gbuffer(&mesh, cam, near, far);
        let n = tri.len();
        let (mut id_mismatch, mut depth_bad) = (0, 0);
        for i in 0..n {
            if tri[i] != r.tri[i] {
                id_mismatch += 1;
            }
            let (dg, dc) = (pos[i][3], r.depth[i]);
            // Tolerance: 1e-4 relative depth (fp32 interpolation vs f64 ray cast).
            if (dg - dc).abs() > 1e-4 * dc.max(1.0) {
                depth_bad += 1;
                continue;
            }
            if tri[i] == r.tri[i] && tri[i] != 0 {
                let ng = Vec3::new(nrm[i][0], nrm[i][1], nrm[i][2]);
                assert!(
                    ng.dot(Vec3::from(r.normal[i])) > 0.9999,
                    "pixel {i}: normal {ng} vs {:?}",
                    r.normal[i]
                );
                // World position = camera centre + depth along the pixel ray.
                let x = (i % 64) as f32 + 0.5;
                let y = (i / 64) as f32 + 0.5;
                let p = cam.center() + cam.ray_dir(glam::Vec2::new(x, y)) * dc;
                let pg = Vec3::new(pos[i][0], pos[i][1], pos[i][2]);
                assert!(
                    (pg - p).length() < 1e-3 * dc.max(1.0),
                    "pixel {i}: position {pg} vs {p}"
                );
            }
        }
        // Edges between triangles may go either way under the two rules: allow 5% of pixels
        // to name another triangle and 2% to land on another surface (silhouettes).
        assert!(
            id_mismatch * 20 <= n,
            "{id_mismatch} of {n} pixels hit another triangle"
        );
        assert!(
            depth_bad * 50 <= n,
            "{depth_bad} of {n} pixels disagree on depth"
        );
    }
    common::assert_no_validation_errors(&gpu);
}

fn random_rays(mesh: &Mesh, n: usize, seed: u64) -> Vec<Ray> {
    let (lo, hi) = mesh.bounds();
    let mut rng = Rng::new(seed);
    (0..n)
        .map(|_| {
            let o = lo
                + (hi - lo)
                    * Vec3::new(
                        rng.range(0.05, 0.95),
                        rng.range(0.05, 0.95),
                        rng.range(0.05, 0.95),
                    );
            let d = Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            )
            .normalize();
            // Some rays are short enough to miss everything.
            let tmax = if rng.f32() < 0.3 {
                rng.range(0.05, 1.0)
            } else {
                100.0
            };
            Ray {
                origin: o.into(),
                tmin: 1e-3,
                dir: d.into(),
                tmax,
            }
        })
        .collect()
}

#[test]
fn ray_query_matches_cpu_brute_force() {
    let gpu = common::gpu();
    let mesh = test_mesh();
    let scene = RayScene::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let caster = RayCaster::new(&gpu).unwrap();
    let rays = random_rays(&mesh, 600, 3);
    let hits = caster.cast(&scene, &rays, false).unwrap();
    let occl = caster.cast(&scene, &rays, true).unwrap();
    let (mut misses, mut ties) = (0, 0);
    for (i, (r, h)) in rays.iter().zip(&hits).enumerate() {
        let (o, d) = (Vec3::from(r.origin), Vec3::from(r.dir));
        let c = cpu::closest_hit(&mesh, o, d, r.tmin, r.tmax);
        // Tolerance: t within 1e-4 relative; barycentrics within 1e-3.
        match c {
            None => {
                misses += 1;
                assert_eq!(
                    h.tri,
                    u32::MAX,
                    "ray {i}: GPU hit {} at t={}, CPU missed",
                    h.tri,
                    h.t
                );
            }
            Some(c) => {
                assert_ne!(
                    h.tri,
                    u32::MAX,
                    "ray {i}: GPU missed, CPU hit {} at {}",
                    c.tri,
                    c.t
                );
                assert!(
                    (h.t - c.t).abs() <= 1e-4 * c.t.max(1.0),
                    "ray {i}: t {} vs {}",
                    h.t,
                    c.t
                );
                if h.tri == c.tri {
                    assert!(
                        (h.bary[0] - c.bary[0]).abs() < 1e-3
                            && (h.bary[1] - c.bary[1]).abs() < 1e-3,
                        "ray {i}: barycentrics"
                    );
                } else {
                    // A tie on a shared edge: the GPU's triangle must be hit at the same t.
                    ties += 1;
                    let [a, b, cc] = mesh.corners(h.tri as usize).map(|v| v.as_dvec3());
                    let t =
                        cpu::ray_triangle(o.as_dvec3(), d.as_dvec3(), a, b, cc).map(|x| x.0 as f32);
                    assert!(
                        t.is_some_and(|t| (t - c.t).abs() <= 1e-4 * c.t.max(1.0)),
                        "ray {i}: triangle {} vs {}",
                        h.tri,
                        c.tri
                    );
                }
            }
        }
        // Occlusion must agree except when the closest hit sits on the segment's end.
        let on_boundary = c.is_some_and(|c| (c.t - r.tmax).abs() < 1e-4 * r.tmax.max(1.0));
        if !on_boundary {
            let cpu_occ = cpu::occluded(&mesh, o, d, r.tmin, r.tmax);
            assert_eq!(occl[i].tri != u32::MAX, cpu_occ, "ray {i}: occlusion");
        }
    }
    assert!(
        misses > 20,
        "the test rays should include misses ({misses})"
    );
    assert!(ties * 50 <= rays.len(), "too many edge ties: {ties}");
    common::assert_no_validation_errors(&gpu);
}

#[test]
fn forced_staging_gives_the_same_results() {
    let gpu = common::gpu();
    // Direct mapping first, then the staging path lavapipe never takes on its own.
    let data: Vec<u32> = (0..10_000u32).map(|i| i.wrapping_mul(2654435761)).collect();
    let direct =
        Buffer::from_slice(&gpu, "direct", vk::BufferUsageFlags::STORAGE_BUFFER, &data).unwrap();
    gpu.set_force_staging(true);
    let staged =
        Buffer::from_slice(&gpu, "staged", vk::BufferUsageFlags::STORAGE_BUFFER, &data).unwrap();
    assert_eq!(staged.download_vec::<u32>().unwrap(), data);
    assert_eq!(direct.download_vec::<u32>().unwrap(), data);
    let part = staged.download_range(400, 40).unwrap();
    assert_eq!(bytemuck_u32(&part), &data[100..110]);

    // A whole pass with staged uploads and readbacks.
    let mesh = test_mesh();
    let scene = RayScene::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let caster = RayCaster::new(&gpu).unwrap();
    let rays = random_rays(&mesh, 200, 9);
    let staged_hits = caster.cast(&scene, &rays, false).unwrap();
    gpu.set_force_staging(false);
    let direct_hits = caster.cast(&scene, &rays, false).unwrap();
    for (a, b) in staged_hits.iter().zip(&direct_hits) {
        assert_eq!((a.tri, a.t.to_bits()), (b.tri, b.t.to_bits()));
    }
    common::assert_no_validation_errors(&gpu);
}

fn bytemuck_u32(b: &[u8]) -> Vec<u32> {
    b.chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

#[test]
fn every_push_struct_matches_its_shaders_block() {
    let layouts = relit_engine::push_layouts();
    for l in &layouts {
        for &s in l.shaders {
            let r = gpu::reflect(s).unwrap();
            assert_eq!(
                l.size, r.push_size,
                "{}: size of {} against {s}",
                l.ty, l.ty
            );
            assert_eq!(
                l.offsets, r.push_offsets,
                "{}: member offsets against {s}",
                l.ty
            );
        }
    }
    // Every shader with push constants has its struct listed.
    for &s in shaders::ALL {
        let listed = layouts.iter().any(|l| l.shaders.contains(&s));
        if gpu::reflect(s).unwrap().push_size > 0 {
            assert!(listed, "{s} has push constants but no push_layout! entry");
        }
    }
    // The reader finds real offsets: bake/surface_cache.comp's push block, whose `light` starts
    // at 32 bytes and is read member by member (4 vec4s).
    let r = gpu::reflect(shaders::BAKE_SURFACE_CACHE).unwrap();
    assert_eq!(
        &r.push_offsets[..],
        &[0, 4, 8, 12, 16, 20, 24, 32, 48, 64, 80]
    );
    // The frame passes share one block (frame/frame_constants.glsl) within the 128 bytes
    // Vulkan guarantees.
    let frame = gpu::reflect(shaders::FRAME_REPROJECT).unwrap().push_size;
    assert!(frame <= 128, "the frame's constants take {frame} bytes");
}

#[test]
fn layouts_come_from_reflection() {
    let r = gpu::reflect(shaders::TRACE_RAYS).unwrap();
    let set0 = &r.sets[&0];
    assert_eq!(set0[&0].0, vk::DescriptorType::ACCELERATION_STRUCTURE_KHR);
    assert_eq!(set0[&1].0, vk::DescriptorType::STORAGE_BUFFER);
    assert_eq!(set0[&2].0, vk::DescriptorType::STORAGE_BUFFER);
    assert_eq!(r.push_size, 8);
    assert_eq!(r.workgroup, Some((64, 1, 1)));
    // The G-buffer's raster stages read the mesh from a vertex buffer: no descriptors.
    let v = gpu::reflect(shaders::RASTER_GBUFFER_VERT).unwrap();
    assert!(v.sets.values().all(|b| b.is_empty()), "{:?}", v.sets);
    assert_eq!(v.push_size, 80, "Camera push block is 5 vec4");
    // Cooperative-matrix kernels take the layout of their portable twin.
    assert_eq!(gpu::layout_source(shaders::NET_CONV_CM), shaders::NET_CONV);
    assert_eq!(gpu::layout_source(shaders::NET_CONV), shaders::NET_CONV);
    // Every embedded shader reflects (the cooperative-matrix ones through their twin, which
    // exists), variants from build.rs's table included.
    assert!(shaders::ALL.contains(&shaders::NET_UPSAMPLE_ADD_LP_F32));
    for &s in shaders::ALL {
        gpu::reflect(s).unwrap_or_else(|e| panic!("{s}: {e}"));
        if s.name().ends_with("_cm.comp") {
            assert_ne!(gpu::layout_source(s), s, "{s} has no portable twin");
        }
    }
}

#[test]
fn pipeline_rejects_wrong_bindings() {
    let gpu = common::gpu();
    let p = Pipeline::compute(&gpu, shaders::TRACE_RAYS).unwrap();
    let b = Buffer::new(
        &gpu,
        "b",
        64,
        vk::BufferUsageFlags::STORAGE_BUFFER,
        MemoryLocation::GpuOnly,
    )
    .unwrap();
    let bind = |binds: &[(&str, gpu::Bind)]| {
        gpu.submit(|cmd| p.bind(cmd, binds, &[0; 8]))
            .unwrap()
            .unwrap_err()
            .to_string()
    };
    let buf = gpu::Bind::Buffer(&b);
    // A buffer where the shader has an acceleration structure.
    let err = bind(&[("tlas", buf), ("Rays", buf), ("Hits", buf)]);
    assert!(
        err.contains("trace/rays.comp") && err.contains("\"tlas\""),
        "{err}"
    );
    let err = bind(&[("Rays", buf)]);
    assert!(err.contains("not given"), "{err}");
    let err = bind(&[("Rayz", buf)]);
    assert!(
        err.contains("no binding named \"Rayz\"") && err.contains("Hits"),
        "{err}"
    );
    common::assert_no_validation_errors(&gpu);
}

/// Reflection names each binding as the GLSL does (a block by its type, an image or
/// acceleration structure by its variable) and reads its access from the decorations.
#[test]
fn bindings_are_named_and_their_access_reflected() {
    use gpu::Access::*;
    let r = gpu::reflect(shaders::FRAME_FEATURES).unwrap();
    let access = |n: &str| r.names.get(n).map(|x| x.1);
    assert_eq!(access("Comp"), Some(Read));
    assert_eq!(access("NetIn"), Some(Write));
    assert_eq!(access("g_pos"), Some(Read));
    let r = gpu::reflect(shaders::TRACE_RAYS).unwrap();
    assert_eq!(r.names["tlas"], (0, Read));
    assert_eq!(r.names["Hits"], (2, Write));
    let r = gpu::reflect(shaders::NET_UPSAMPLE_ADD).unwrap();
    assert_eq!(r.names["Dst"].1, ReadWrite);
    let r = gpu::reflect(shaders::BAKE_MIRROR).unwrap();
    assert_eq!(r.names["Views"].1, Read, "a uniform block is read");
    // Every shader's bindings all have names.
    for &s in shaders::ALL {
        let r = gpu::reflect(s).unwrap();
        let n: usize = r.sets.values().map(|b| b.len()).sum();
        assert_eq!(r.names.len(), n, "{s}");
    }
}

/// The pass graph puts a barrier exactly where a pass uses what an earlier one wrote (or
/// writes what one read), telling resources apart by handle, not by name; the barrier names
/// each buffer written since the last one, and nothing else.
#[test]
fn the_pass_graph_derives_its_barriers() {
    use relit_engine::view::compose::font_words;
    let gpu = common::gpu();
    let p = Pipeline::compute(&gpu, shaders::VIEW_COMPOSE).unwrap();
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let px: Vec<u32> = (0..64u32).map(|i| i * 0x010203).collect();
    let a = Buffer::from_slice(&gpu, "a", usage, &px).unwrap();
    let font = Buffer::from_slice(&gpu, "font", usage, &font_words()).unwrap();
    let text = Buffer::from_slice(&gpu, "text", usage, &[0u32; 4]).unwrap();
    let new = |n| {
        Buffer::new(
            &gpu,
            n,
            256,
            usage | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::GpuOnly,
        )
        .unwrap()
    };
    let (b, c, d) = (new("b"), new("c"), new("d"));
    let push = relit_engine::view::compose::push((8, 8), (8, 8), None, false);
    let push = bytemuck::bytes_of(&push);
    let barriers = gpu
        .submit(|cmd| -> relit_engine::error::Result<u32> {
            let mut g = gpu::Graph::new(&gpu, cmd, None);
            g.set("Font", gpu::Bind::Buffer(&font))
                .set("Text", gpu::Bind::Buffer(&text));
            g.set("Src", gpu::Bind::Buffer(&a))
                .set("Dst", gpu::Bind::Buffer(&b));
            g.dispatch("a to b", &p, push, (8, 8, 1))?;
            // Independent of the first: no barrier.
            g.set("Dst", gpu::Bind::Buffer(&d));
            g.dispatch("a to d", &p, push, (8, 8, 1))?;
            assert_eq!(g.barriers.commands, 0);
            // Reads b, which the first pass wrote (under the name "Dst"): a barrier.
            g.set("Src", gpu::Bind::Buffer(&b))
                .set("Dst", gpu::Bind::Buffer(&c));
            g.dispatch("b to c", &p, push, (8, 8, 1))?;
            // One command with a buffer barrier for b and one for d, the buffers written.
            let want = gpu::BarrierCount {
                commands: 1,
                buffers: 2,
                ..Default::default()
            };
            assert_eq!(g.barriers, want);
            // A pass's own binding that its shader does not declare, and a declared one the
            // graph lacks, are errors naming the shader; neither records anything.
            let misspelt = [("Dest", gpu::Bind::Buffer(&c))];
            let e = g.pass("typo", &p, misspelt, push, (8, 8, 1)).unwrap_err();
            assert!(
                e.to_string().contains("\"Dest\"") && e.to_string().contains("compose"),
                "{e}"
            );
            let mut bare = gpu::Graph::new(&gpu, cmd, None);
            bare.set("Src", gpu::Bind::Buffer(&a));
            let e = bare.dispatch("bare", &p, push, (8, 8, 1)).unwrap_err();
            assert!(
                e.to_string().contains("compose") && e.to_string().contains("\"Dst\""),
                "{e}"
            );
            Ok(g.barriers.commands)
        })
        .unwrap()
        .unwrap();
    assert_eq!(barriers, 1);
    let opaque: Vec<u32> = px.iter().map(|v| v | 0xff00_0000).collect();
    assert_eq!(c.download_vec::<u32>().unwrap(), opaque);
    assert_eq!(d.download_vec::<u32>().unwrap(), opaque);
    common::assert_no_validation_errors(&gpu);
}

/// Timer spans come from the graph and add no barrier to a chain whose passes depend on each
/// other: a span per pass, or one per group, and the same barriers as without a timer. On
/// lavapipe a span before work that needs no barrier gets one (it reads a timestamp at a
/// flush).
#[test]
fn timer_spans_add_no_barriers_to_a_dependent_chain() {
    use relit_engine::view::compose::{font_words, push};
    let gpu = common::gpu();
    let p = Pipeline::compute(&gpu, shaders::VIEW_COMPOSE).unwrap();
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let font = Buffer::from_slice(&gpu, "font", usage, &font_words()).unwrap();
    let text = Buffer::from_slice(&gpu, "text", usage, &[0u32; 4]).unwrap();
    let bufs: Vec<Buffer> = (0..4)
        .map(|i| Buffer::from_slice(&gpu, &format!("b{i}"), usage, &[i; 64]).unwrap())
        .collect();
    let push = push((8, 8), (8, 8), None, false);
    let push = bytemuck::bytes_of(&push);
    // b0 → b1 → b2 → b3, then b0 → b1 again after a group (grouped: one span).
    let chain = |timer: Option<&mut Timer>, grouped: bool| {
        gpu.submit(|cmd| -> relit_engine::error::Result<gpu::BarrierCount> {
            let mut g = gpu::Graph::new(&gpu, cmd, timer);
            let steps = |g: &mut gpu::Graph| -> relit_engine::error::Result<()> {
                for i in 0..3 {
                    let (src, dst) = (gpu::Bind::Buffer(&bufs[i]), gpu::Bind::Buffer(&bufs[i + 1]));
                    let binds = [
                        ("Src", src),
                        ("Dst", dst),
                        ("Font", gpu::Bind::Buffer(&font)),
                        ("Text", gpu::Bind::Buffer(&text)),
                    ];
                    let uses = [gpu::Use::Read(src), gpu::Use::Write(dst)];
                    g.compute(&format!("step {i}"), &uses, |cmd| {
                        p.dispatch(cmd, &binds, push, (8, 8, 1))
                    })?;
                }
                Ok(())
            };
            match grouped {
                true => g.group("chain", steps)?,
                false => steps(&mut g)?,
            }
            Ok(g.barriers)
        })
        .unwrap()
        .unwrap()
    };
    let plain = chain(None, false);
    assert_eq!((plain.commands, plain.for_timer), (2, 0));
    for grouped in [false, true] {
        let mut timer = Timer::new(&gpu, 8).unwrap();
        let timed = chain(Some(&mut timer), grouped);
        let spans = timer.read().unwrap();
        let labels: Vec<&str> = spans.iter().map(|s| s.0.as_str()).collect();
        let want: &[&str] = match grouped {
            true => &["chain"],
            false => &["step 0", "step 1", "step 2"],
        };
        assert_eq!(labels, want);
        assert!(
            spans.iter().all(|s| s.1.is_finite() && s.1 >= 0.0),
            "{spans:?}"
        );
        // On lavapipe the first span's timestamp needs a flush before the first pass: one
        // barrier more; a GPU needs none.
        let extra = u32::from(gpu.caps.device_type == vk::PhysicalDeviceType::CPU);
        let want = (2 + extra, extra);
        assert_eq!((timed.commands, timed.for_timer), want, "grouped {grouped}");
    }
    common::assert_no_validation_errors(&gpu);
}

#[test]
fn device_choice_errors_name_the_devices() {
    let err = Gpu::new(&GpuOptions {
        device: DeviceChoice::Name("no-such-gpu-xyz".into()),
        validation: false,
        ..Default::default()
    })
    .err()
    .expect("must fail");
    assert!(err.to_string().contains("no-such-gpu-xyz"), "{err}");
    let err = Gpu::new(&GpuOptions {
        device: DeviceChoice::Index(99),
        validation: false,
        ..Default::default()
    })
    .err()
    .expect("must fail");
    assert!(err.to_string().contains("out of range"), "{err}");
    assert!(matches!(DeviceChoice::parse("1"), DeviceChoice::Index(1)));
    assert!(matches!(
        DeviceChoice::parse("llvmpipe"),
        DeviceChoice::Name(_)
    ));
}

/// The backend follows the device's capabilities, never its name: fp16 storage takes the
/// cooperative-matrix kernels exactly when a shape fits, fp32 the CPU-shaped ones on CPU devices
/// whose subgroups fit them.
#[test]
fn network_backend_follows_capabilities() {
    use relit_engine::net::{backend_for, coop_tile, lanes_fit, Backend, NetKernels, Storage};
    let gpu = common::gpu();
    assert!(gpu.caps.missing().is_empty());
    for storage in [Storage::F16, Storage::F32] {
        let k = NetKernels::new(&gpu, storage).unwrap();
        assert_eq!(k.backend, backend_for(&gpu.caps, storage));
    }
    assert_eq!(
        backend_for(&gpu.caps, Storage::F16) == Backend::CoopMatrix,
        coop_tile(&gpu.caps).is_some()
    );
    let cpu = gpu.caps.device_type == vk::PhysicalDeviceType::CPU;
    assert_eq!(
        backend_for(&gpu.caps, Storage::F32) == Backend::CpuLanes,
        cpu && lanes_fit(&gpu.caps)
    );
    // The CPU-shaped conv shares weights between 8 lanes: narrower subgroups, or none of
    // subgroupBroadcast, take the portable kernels.
    for (lanes, broadcast) in [(4, true), (8, false)] {
        let mut caps = gpu.caps.clone();
        caps.subgroup_size = lanes;
        caps.subgroup_broadcast = broadcast;
        assert_eq!(backend_for(&caps, Storage::F32), Backend::Portable);
    }
    if common::require_coop() {
        assert!(coop_tile(&gpu.caps).is_some(), "{:?}", gpu.caps.coop_matrix);
    }
    common::assert_no_validation_errors(&gpu);
}

#[test]
fn timestamps_measure_a_dispatch() {
    let gpu = common::gpu();
    let mesh = test_mesh();
    let scene = RayScene::new(&gpu, &mesh.positions, &mesh.triangles).unwrap();
    let caster = RayCaster::new(&gpu).unwrap();
    let rays = random_rays(&mesh, 256, 5);
    let rb = Buffer::from_slice(&gpu, "rays", vk::BufferUsageFlags::STORAGE_BUFFER, &rays).unwrap();
    let hb = Buffer::new(
        &gpu,
        "hits",
        256 * 16,
        vk::BufferUsageFlags::STORAGE_BUFFER,
        MemoryLocation::GpuOnly,
    )
    .unwrap();
    let mut timer = Timer::new(&gpu, 2).unwrap();
    gpu.submit(|cmd| {
        let mut g = gpu::Graph::new(&gpu, cmd, Some(&mut timer));
        caster.record(&mut g, &scene, &rb, &hb, 256, false).unwrap();
    })
    .unwrap();
    let t = timer.read().unwrap();
    assert_eq!(t.len(), 1);
    assert_eq!(t[0].0, "ray cast");
    // Only sanity: a finite, non-negative span (speed is for `relit bench`).
    assert!(t[0].1.is_finite() && t[0].1 >= 0.0, "{t:?}");
    common::assert_no_validation_errors(&gpu);
}

#[test]
fn gemm_portable_matches_cpu_and_coop_matrix_module_is_built() {
    use half::f16;
    use relit_engine::net::{coop_tile, Backend, CoopTile, Gemm};
    let gpu = common::gpu();
    let (m, n, k) = (32u32, 48u32, 80u32);
    let mut rng = Rng::new(17);
    let a: Vec<f16> = (0..m * k)
        .map(|_| f16::from_f32(rng.range(-1.0, 1.0)))
        .collect();
    let b: Vec<f16> = (0..k * n)
        .map(|_| f16::from_f32(rng.range(-1.0, 1.0)))
        .collect();
    let gemm = Gemm::with_backend(&gpu, Backend::Portable).unwrap();
    let c = gemm.run(&a, &b, m, n, k).unwrap();
    for i in 0..m as usize {
        for j in 0..n as usize {
            let r: f64 = (0..k as usize)
                .map(|q| a[i * k as usize + q].to_f64() * b[q * n as usize + j].to_f64())
                .sum();
            // fp32 accumulation of 80 products of fp16 inputs: 1e-4 absolute.
            assert!(
                (c[i * n as usize + j] as f64 - r).abs() < 1e-4,
                "c[{i},{j}] = {} vs {r}",
                c[i * n as usize + j]
            );
        }
    }
    assert!(
        gemm.run(&a, &b, 30, n, k).is_err(),
        "sizes must be tile multiples"
    );

    // The cooperative-matrix module is compiled, carries the capability (OpCapability
    // CooperativeMatrixKHR = 6022), and takes its twin's layout.
    let words = gpu::spirv(shaders::NET_GEMM_CM).unwrap();
    assert!(words
        .windows(2)
        .any(|w| w[0] == (2 << 16 | 17) && w[1] == 6022));
    let (cm, portable) = (
        gpu::reflect(shaders::NET_GEMM_CM).unwrap(),
        gpu::reflect(shaders::NET_GEMM).unwrap(),
    );
    assert_eq!(cm.sets, portable.sets);
    assert_eq!(cm.push_size, 12);

    // Selection: a shape with fp16 A/B, fp32 accumulators and sides dividing 16; the largest.
    let mut caps = gpu.caps.clone();
    caps.coop_matrix.clear();
    caps.subgroup_size = 32;
    assert_eq!(coop_tile(&caps), None);
    let shape = |(m, n, k), c| gpu::CoopMatrixShape {
        m,
        n,
        k,
        a: vk::ComponentTypeKHR::FLOAT16,
        b: vk::ComponentTypeKHR::FLOAT16,
        c,
        result: c,
        scope: vk::ScopeKHR::SUBGROUP,
    };
    let (f16, f32) = (vk::ComponentTypeKHR::FLOAT16, vk::ComponentTypeKHR::FLOAT32);
    caps.coop_matrix.push(shape((16, 16, 16), f16));
    assert_eq!(coop_tile(&caps), None, "fp16 accumulators do not fit");
    caps.coop_matrix.push(shape((16, 16, 32), f32));
    caps.coop_matrix.push(shape((4, 4, 4), f32));
    assert_eq!(
        coop_tile(&caps),
        None,
        "k = 32 does not divide 16; 4x4 needs 16 tiles"
    );
    caps.coop_matrix.push(shape((8, 8, 8), f32));
    let tile = |subgroup, m, n, k| Some(CoopTile { subgroup, m, n, k });
    assert_eq!(coop_tile(&caps), tile(32, 8, 8, 8));
    caps.coop_matrix.push(shape((16, 8, 16), f32));
    assert_eq!(
        coop_tile(&caps),
        tile(32, 16, 8, 16),
        "the largest fitting shape"
    );
    caps.subgroup_size = 8;
    assert_eq!(coop_tile(&caps), tile(8, 16, 8, 16));
    // On this device the selected backend runs and matches the CPU.
    let sel = Gemm::new(&gpu).unwrap();
    assert_eq!(
        sel.backend == Backend::CoopMatrix,
        coop_tile(&gpu.caps).is_some()
    );
    let got = sel.run(&a, &b, m, n, k).unwrap();
    let e = got
        .iter()
        .zip(&c)
        .fold(0f32, |e, (x, y)| e.max((x - y).abs()));
    // Portable: the same kernel as above; cooperative matrix: fp32 accumulation in another order.
    assert!(e < 1e-4, "{:?} gemm: max difference {e}", sel.backend);
    common::assert_no_validation_errors(&gpu);
}

/// The storage-access probe behind `relit bench gather`: both ways of reading the table give the
/// CPU reference's sums (exact: 16 small integers and binary fractions per lane).
#[test]
fn gather_probe_matches_cpu_both_ways() {
    use relit_engine::gpu::gather::{reference, Access, GatherProbe};
    let gpu = common::gpu();
    let table: Vec<[f32; 4]> = (0..1024)
        .map(|i| [i as f32, 1.0, 0.5, (i % 7) as f32])
        .collect();
    let probe = GatherProbe::new(&gpu, &table, 1000).unwrap();
    let want = reference(&table, 1000);
    for access in [Access::StorageBuffer, Access::DeviceAddress] {
        let (got, ms) = probe.run(access).unwrap();
        assert_eq!(&got[..1000], &want[..], "{access:?}");
        assert!(ms.is_finite() && ms >= 0.0);
    }
    assert!(
        GatherProbe::new(&gpu, &table[..1000], 10).is_err(),
        "not a power of two"
    );
    common::assert_no_validation_errors(&gpu);
}

/// The viewer's compose pass (`view/compose.comp`) against its CPU reference: a frame shown 1:1
/// is copied exactly; scaled into a window of another aspect it is bilinear within 1 code
/// value with black bars, the HUD's glyphs and box exact, in either byte order.
#[test]
fn compose_scales_the_frame_and_draws_the_hud_as_the_cpu_reference() {
    use relit_engine::view::compose::{font_words, push, reference, Compose, HudText};
    let gpu = common::gpu();
    let (sw, sh) = (13u32, 9u32);
    let mut rng = Rng::new(7);
    let src: Vec<u8> = (0..sw * sh * 4)
        .map(|_| rng.range(0.0, 255.99) as u8)
        .collect();
    let buf =
        Buffer::from_slice(&gpu, "frame", vk::BufferUsageFlags::STORAGE_BUFFER, &src).unwrap();
    let mut compose = Compose::new(&gpu).unwrap();
    let hud = HudText::new(&["12.5 fps".into(), "Ratio {x}".into()]);
    for (dst, hud, bgr) in [
        ((sw, sh), None, false),
        ((50, 21), Some(&hud), false),
        ((31, 40), Some(&hud), true),
        ((960, 500), Some(&hud), true),
    ] {
        gpu.submit(|cmd| {
            let mut g = gpu::Graph::new(&gpu, cmd, None);
            compose.record(&mut g, &buf, (sw, sh), dst, hud, bgr)?;
            g.finish()
        })
        .unwrap()
        .unwrap();
        let got = compose
            .output()
            .download_range(0, (dst.0 * dst.1 * 4) as u64)
            .unwrap();
        let p = push((sw, sh), dst, hud, bgr);
        let text = hud.map(|t| t.cells.clone()).unwrap_or_default();
        let want = reference(&src, &p, &text, &font_words());
        let worst = (got.iter().zip(&want))
            .map(|(a, b)| (*a as i32 - *b as i32).abs())
            .max()
            .unwrap();
        let limit = if dst == (sw, sh) { 0 } else { 1 };
        assert!(
            worst <= limit,
            "{dst:?}: compose differs from the reference by {worst}"
        );
        if dst == (sw, sh) {
            assert_eq!(
                got,
                src.chunks(4)
                    .flat_map(|c| [c[0], c[1], c[2], 255])
                    .collect::<Vec<_>>()
            );
        }
        if hud.is_some() {
            let white = want.chunks(4).filter(|c| c[..3] == [255, 255, 255]).count();
            assert!(
                white > 20,
                "{dst:?}: the reference draws the HUD's text ({white} px)"
            );
        }
    }
    common::assert_no_validation_errors(&gpu);
}
