//! The Mitsuba scene built from a scenegen description matches Relit's geometry: Mitsuba's depth
//! AOV of the true mesh vs the engine's rasterized depth of the same mesh and cameras.

mod common;

use relit_engine::gpu::RayScene;
use relit_engine::raster::GbufferPass;
use relit_engine::scene::{image::load_rgb, Mesh, Scene};
use relit_scenegen::room::RoomOptions;

#[test]
fn mitsuba_depth_matches_engine_raster_of_the_true_mesh() {
    let dir = common::tempdir("gt-depth");
    let opts = RoomOptions {
        views: 3,
        width: 48,
        height: 36,
        extra_lights: 1,
        test_views: 1,
        // The camera set this test's tolerances were measured on.
        light_views: 0,
        lamp_colours: Default::default(),
        proxy_error: 1.0,
        finishes: Default::default(),
    };
    relit_scenegen::generate(&dir, 11, &opts).unwrap();
    common::render_ground_truth(&dir, &["--only", "aov"]);

    let scene = Scene::load(&dir).unwrap();
    let true_mesh = Mesh::load(scene.true_mesh_path.as_ref().unwrap()).unwrap();
    let gpu = common::gpu();
    let rs = RayScene::new(&gpu, &true_mesh.positions, &true_mesh.triangles).unwrap();
    let pass = GbufferPass::new(&gpu).unwrap();
    let syn = scene.synthetic.as_ref().unwrap();
    let mut cams: Vec<(String, relit_engine::scene::Camera)> = scene
        .views
        .iter()
        .map(|v| (v.name.clone(), v.camera.clone()))
        .collect();
    for t in &syn.test_views {
        cams.push((t.name.clone(), t.camera.to_camera(&dir, &t.name).unwrap()));
    }
    for (name, cam) in &cams {
        let g = pass
            .render(&rs, cam, 0.01, 100.0)
            .unwrap()
            .download()
            .unwrap();
        let mts = load_rgb(&dir.join(format!("gt/aov/{name}.depth.exr"))).unwrap();
        let n = g.tri.len();
        let mut rel = Vec::new();
        let mut bad = 0;
        for i in 0..n {
            let (ze, zm) = (g.pos_depth[i][3], mts.pixels[i][0]);
            let r = (ze - zm).abs() / zm.max(1e-3);
            // Half-float storage of depth: 2^-11 relative; allow 2e-3.
            if r > 2e-3 {
                bad += 1;
            }
            rel.push(r);
        }
        if bad * 20 > n {
            for &i in &[0usize, 47, 48 * 35, n - 1, n / 2] {
                eprintln!(
                    "px {i}: engine {} mitsuba {}",
                    g.pos_depth[i][3], mts.pixels[i][0]
                );
            }
        }
        rel.sort_by(|a, b| a.total_cmp(b));
        // Silhouette pixels may fall either way: up to 2% may differ; the median must be at
        // half precision.
        assert!(
            bad * 50 <= n,
            "view {name}: {bad} of {n} pixels differ in depth"
        );
        assert!(
            rel[n / 2] < 1e-3,
            "view {name}: median relative depth error {}",
            rel[n / 2]
        );
    }
    common::assert_no_validation_errors(&gpu);
}
