//! The frame's renderer: its pipelines, per-resolution buffers, the frame's constants (one
//! [`FrameConstants`] push block for every pass but view culling, filled once a frame), and the
//! passes of one frame recorded in order through a [`Graph`].

use std::sync::Arc;

use super::constants::mode_code;
use super::{
    features, glossy, irradiance, live, output, reproject, sight_cache, target_mirror, view_cull,
    FrameBuffers, FrameConstants, FrameScene, Lighting, Mode,
};
use crate::bake::GpuLight;
use crate::error::{Error, Result};
use crate::gpu::{bytes_of, vk, BarrierCount, Bind, Buffer, Gpu, Graph, Pipeline, Timer};
use crate::net::{Network, Storage, INPUT_CHANNELS};
use crate::raster::GbufferPass;
use crate::scene::{Camera, Light};

/// The frame pipelines and, optionally, the network.
pub struct Renderer {
    pub gpu: Arc<Gpu>,
    pub scene: FrameScene,
    pub net: Option<Network>,
    pub storage: Storage,
    gbuffer: GbufferPass,
    reproject: Pipeline,
    irradiance: Pipeline,
    target_mirror: Pipeline,
    glossy_sums: Pipeline,
    glossy: Pipeline,
    features: Pipeline,
    output: Pipeline,
    view_cull: Pipeline,
    /// The active views of the last frame, ascending.
    active: Vec<u32>,
    /// When frames choose their active views ([`view_cull`]) and how many.
    pub culling: view_cull::Culling,
    /// Buffers per resolution, the last frame's first: the viewer alternates a reduced
    /// resolution while moving with the full one when still, so two stay allocated.
    bufs: Vec<FrameBuffers>,
    /// An input view left out of every pass (leave-one-out inputs for training on input
    /// views: `relit dump` of an input camera).
    pub exclude: Option<u32>,
    /// Lights being placed or moved (the viewer).
    pub live: live::LiveLights,
    /// Skip the passes that only feed the network (target mirror, features) in the modes that
    /// do not run it: ratio and ULR frames for the screen cost half as much. Off by default,
    /// since `relit dump` and the tests read those passes' buffers after a ULR frame.
    pub display_only: bool,
    /// Fill the holes no input view sees (ratio, glossy and ULR modes) from the nearest covered
    /// pixels (`output.glsl`'s `hole_fill`): the viewer's moving frame, which would show them
    /// black. Off by default: renders and evaluations score holes as the mode leaves them.
    pub fill_holes: bool,
    /// The view-dependent fit per triangle (frame/glossy_fit/) and the view left out when it
    /// was made; None until a frame needs it. Zeros while it is being made.
    pub(super) glossy_fit: Option<(Option<u32>, Buffer)>,
    pub(super) fitting: bool,
    zero_fit: Buffer,
    /// Read which still lights a glossy pixel sees from the sight cache ([`sight_cache`]) instead
    /// of tracing them (on by default).
    pub use_sight_cache: bool,
    /// The sight cache's layout and pass (made with the first glossy frame) and the cache.
    pub(super) sight_pass: Option<sight_cache::SightPass>,
    pub(super) sight: Option<sight_cache::SightCache>,
    /// The live lights as the last glossy frame had them (a settled one gets a column).
    pub(super) sight_prev: Vec<(usize, GpuLight)>,
    /// The barriers the last frame's graphs recorded (`relit bench frame` prints them).
    barriers: std::cell::Cell<BarrierCount>,
}

/// The novel view's G-buffer, as the frame's passes name it.
const GBUFFER: [&str; 3] = ["g_pos", "g_nrm", "g_tri"];

/// Near and far planes of the novel view's G-buffer (m): the input views'.
pub use crate::bake::views::{FAR, NEAR};

impl Renderer {
    pub fn new(
        gpu: &Arc<Gpu>,
        scene: FrameScene,
        net: Option<Network>,
        storage: Storage,
    ) -> Result<Renderer> {
        if let Some(n) = &net {
            if n.kernels.storage != storage {
                return Err(Error::Other(
                    "the network's storage type differs from the renderer's".into(),
                ));
            }
            if n.config.in_channels != INPUT_CHANNELS || n.config.out_channels != 6 {
                return Err(Error::Other(format!(
                    "the network takes {} channels and returns {}; the frame needs {} in, 6 out",
                    n.config.in_channels, n.config.out_channels, INPUT_CHANNELS
                )));
            }
        }
        let (feat, out) = match storage {
            Storage::F16 => (features::SHADER_F16, output::SHADER_F16),
            Storage::F32 => (features::SHADER_F32, output::SHADER_F32),
        };
        let live = live::LiveLights::new(gpu, &scene.geom, scene.albedo.as_deref())?;
        Ok(Renderer {
            live,
            gbuffer: GbufferPass::new(gpu)?,
            reproject: Pipeline::compute(gpu, reproject::SHADER)?,
            irradiance: Pipeline::compute(gpu, irradiance::SHADER)?,
            target_mirror: Pipeline::compute(gpu, target_mirror::SHADER)?,
            glossy_sums: Pipeline::compute(gpu, glossy::SUMS_SHADER)?,
            glossy: Pipeline::compute(gpu, glossy::SHADER)?,
            features: Pipeline::compute(gpu, feat)?,
            output: Pipeline::compute(gpu, out)?,
            view_cull: Pipeline::compute(gpu, view_cull::SHADER)?,
            active: Vec::new(),
            culling: view_cull::Culling::default(),
            gpu: gpu.clone(),
            scene,
            net,
            storage,
            bufs: Vec::new(),
            exclude: None,
            display_only: false,
            fill_holes: false,
            glossy_fit: None,
            fitting: false,
            use_sight_cache: true,
            sight_pass: None,
            sight: None,
            sight_prev: Vec::new(),
            zero_fit: Buffer::from_slice(
                gpu,
                "glossy fit (none)",
                vk::BufferUsageFlags::STORAGE_BUFFER,
                &[[0f32; 4]],
            )?,
            barriers: Default::default(),
        })
    }

    /// At most this many resolutions keep their buffers.
    const RESOLUTIONS: usize = 2;

    fn buffers(&mut self, width: u32, height: u32) -> Result<&FrameBuffers> {
        match (self.bufs.iter()).position(|b| (b.width, b.height) == (width, height)) {
            Some(i) => {
                let b = self.bufs.remove(i);
                self.bufs.insert(0, b);
            }
            None => {
                self.bufs.truncate(Self::RESOLUTIONS - 1);
                let b = self.new_buffers(width, height)?;
                self.bufs.insert(0, b);
            }
        }
        Ok(&self.bufs[0])
    }

    fn new_buffers(&self, width: u32, height: u32) -> Result<FrameBuffers> {
        let net = self.net.as_ref();
        FrameBuffers::new(&self.gpu, &self.scene, (net, self.storage), width, height)
    }

    /// Places added light `layer` (a new one when `layer` is the count of added lights) at
    /// `light` and makes it live: drawn there and lit from the next frame, its surface cache
    /// refined by [`Renderer::refine_live`]. A new light needs one more intensity in the
    /// `Lighting` passed to `render`.
    pub fn set_live_light(&mut self, layer: usize, light: &Light) -> Result<()> {
        let before = self.scene.lights.len();
        self.live.set(layer, &GpuLight::new(light))?;
        self.scene.set_emitter(layer, light)?;
        if self.scene.lights.len() != before {
            // The intensity buffer holds one float per added light.
            self.bufs.clear();
        }
        Ok(())
    }

    /// As [`Renderer::set_live_light`] with a finished surface cache (no refinement).
    pub fn set_live_light_cached(
        &mut self,
        layer: usize,
        light: &Light,
        cache: Vec<[f32; 4]>,
    ) -> Result<()> {
        self.live
            .set_converged(layer, &GpuLight::new(light), cache)?;
        self.scene.set_emitter(layer, light)
    }

    /// Added light `layer` reads its baked maps again, drawn at `light` (its baked place).
    pub fn unset_live_light(&mut self, layer: usize, light: &Light) -> Result<()> {
        if self.live.is_live(layer) {
            self.live.unset(layer)?;
            self.scene.set_emitter(layer, light)?;
        }
        Ok(())
    }

    /// One refinement step of the live lights' caches; whether anything changed.
    pub fn refine_live(&mut self) -> Result<bool> {
        // The texels the last frame shows converge first: what the user looks at.
        let focus = match self.bufs.first() {
            Some(b) if self.live.count() > 0 => {
                let tri: Vec<u32> =
                    bytemuck::pod_collect_to_vec(&b.gbuf.tri.download(vk::ImageLayout::GENERAL)?);
                Some(self.live.texels_shown(&tri))
            }
            _ => None,
        };
        self.live.refine(&self.scene.mesh, focus.as_deref())
    }

    /// Renders `cam` under `lighting` and waits; read the results with [`Renderer::buffers_ref`].
    /// With a timer: one span per pass.
    pub fn render(
        &mut self,
        cam: &Camera,
        lighting: &Lighting,
        mode: Mode,
        exposure: f32,
        mut timer: Option<&mut Timer>,
    ) -> Result<()> {
        self.check_frame(lighting, mode)?;
        if self.runs_glossy(mode) {
            self.ensure_glossy_fit()?;
            self.ensure_sight_cache(lighting)?;
        }
        self.buffers(cam.width, cam.height)?;
        self.barriers.set(BarrierCount::default());
        let culled = self.cull_views(cam, timer.as_deref_mut())?;
        let b = &self.bufs[0];
        b.active.upload(bytemuck::cast_slice(&self.active))?;
        let mut ints = lighting.intensities.clone();
        ints.resize(self.scene.lights.len().max(1), 0.0);
        b.intensity.upload(bytemuck::cast_slice(&ints))?;
        let keep = lighting.keep_buffer(self.scene.originals.len());
        b.keep.upload(bytemuck::cast_slice(&keep))?;
        b.sight_cols
            .upload(bytemuck::cast_slice(&self.sight_columns(lighting)))?;
        b.camera.upload(bytes_of(&cam.to_gpu(NEAR, FAR)))?;
        let fc = self.frame_constants(cam, lighting, mode, exposure);
        let push = bytes_of(&fc);
        let threads = (cam.width * cam.height, 1, 1);
        let tiles = (super::sight::tiles(cam.width, cam.height), 1, 1);
        // The passes that only feed the network (see `display_only`).
        let inputs = mode.needs_network() || !self.display_only;
        let gpu = self.gpu.clone();
        let res = gpu.submit(|cmd| -> Result<BarrierCount> {
            let mut g = Graph::new(&gpu, cmd, timer);
            self.resources(&mut g, b);
            if culled {
                g.written_before(&GBUFFER)?;
            } else {
                self.record_gbuffer(&mut g, b, cam)?;
            }
            g.dispatch("reproject", &self.reproject, push, threads)?;
            g.dispatch("irradiance", &self.irradiance, push, threads)?;
            if inputs {
                g.dispatch("target mirror", &self.target_mirror, push, threads)?;
            }
            if self.runs_glossy(mode) {
                // The sums only feed the fit per surface (frame/glossy_fit/).
                match self.fitting {
                    true => g.dispatch("glossy sums", &self.glossy_sums, push, threads)?,
                    // Its workgroups are tiles (frame/sight.rs).
                    false => g.dispatch_groups("glossy layer", &self.glossy, push, tiles)?,
                }
            }
            if inputs {
                g.dispatch("features", &self.features, push, threads)?;
            }
            if mode.needs_network() {
                let (net, nb) = (self.net.as_ref().unwrap(), b.net.as_ref().unwrap());
                net.record(&mut g, nb, &b.input)?;
            }
            g.dispatch("output", &self.output, push, threads)?;
            Ok(g.barriers)
        })?;
        self.add_barriers(&res?);
        Ok(())
    }

    /// The barriers of the last frame: every graph it recorded, the view culling's included.
    pub fn last_barriers(&self) -> BarrierCount {
        self.barriers.get()
    }

    fn add_barriers(&self, c: &BarrierCount) {
        let mut all = self.barriers.get();
        all.add(c);
        self.barriers.set(all);
    }

    /// Whether a frame in `mode` runs the view-dependent layer: glossy mode, and the network
    /// modes of a network whose base is glossy mode's image.
    pub fn runs_glossy(&self, mode: Mode) -> bool {
        let base = self.net.as_ref().map(|n| n.config.base);
        mode.needs_glossy() || (mode.needs_network() && base == Some(crate::net::NetBase::Glossy))
    }

    /// The viewer's cheap frame while anything moves, for the chosen `mode`: ULR and ratio as
    /// they are; glossy mode for glossy mode and for a network whose base is glossy mode's
    /// image (its highlights then move with the walk and a dragged lamp); ratio otherwise, as
    /// the image the network corrects.
    pub fn moving_mode(&self, mode: Mode) -> Mode {
        match mode {
            Mode::Ulr | Mode::Ratio | Mode::Glossy => mode,
            _ if self.runs_glossy(mode) => Mode::Glossy,
            _ => Mode::Ratio,
        }
    }

    /// What a frame needs before anything is recorded: weights for a network mode, one
    /// intensity per added light, and every lit light baked (or live).
    fn check_frame(&self, lighting: &Lighting, mode: Mode) -> Result<()> {
        if mode.needs_network() && self.net.is_none() {
            return Err(Error::Other(format!(
                "{mode:?} mode needs weights (--weights FILE.safetensors); use --mode ratio or ulr"
            )));
        }
        if lighting.intensities.len() != self.scene.lights.len() {
            return Err(Error::Other(format!(
                "lighting has {} intensities; the scene has {} added lights",
                lighting.intensities.len(),
                self.scene.lights.len()
            )));
        }
        if let Some(name) = (self.scene.lights.iter().enumerate()).find_map(|(i, n)| {
            let lit = lighting.intensities[i] != 0.0 && !self.live.is_live(i);
            (lit && self.scene.unbaked.contains(n)).then_some(n)
        }) {
            return Err(Error::Other(format!(
                "added light \"{name}\" is lit but not baked: bake it first (`relit bake SCENE --lights {name}`)"
            )));
        }
        let norig = self.scene.originals.len();
        if lighting.originals.len() > norig {
            return Err(Error::Other(format!(
                "lighting has {} original-light factors; the scene declares {norig} original lights",
                lighting.originals.len()
            )));
        }
        if lighting.per_light() && norig >= 2 && self.scene.split == 0 {
            return Err(Error::Other(
                "a factor for one original light needs the original lights' entries in the bake: \
                 `relit bake SCENE --lights all` (render and fly bake them when a lighting they \
                 render sets such a factor)"
                    .into(),
            ));
        }
        Ok(())
    }

    /// The frame's constants for `cam` (after `cull_views` chose the views): every pass's push
    /// constants but view culling's.
    fn frame_constants(
        &self,
        cam: &Camera,
        lighting: &Lighting,
        mode: Mode,
        exposure: f32,
    ) -> FrameConstants {
        let s = &self.scene;
        let net = self.net.as_ref().map(|n| &n.config);
        FrameConstants {
            eye: cam.center().extend(1.0).into(),
            width: cam.width,
            height: cam.height,
            view_w: s.views.width,
            view_h: s.views.height,
            nviews: s.views.count,
            nactive: self.active.len() as u32,
            exclude: self.exclude.unwrap_or(u32::MAX),
            nlights: s.lights.len() as u32,
            norig: s.originals.len() as u32,
            nlive: self.live.count(),
            live_mask: self.live.mask(),
            nsplit: s.split,
            split_layer: s.split_layer,
            per_light: lighting.per_light() as u32,
            alpha_dim: lighting.alpha_dim,
            mode: mode_code(mode),
            exposure,
            fill: self.fill_holes as u32,
            base: match net.map(|c| c.base) {
                Some(crate::net::NetBase::Ratio) => 1,
                Some(crate::net::NetBase::Glossy) => 2,
                _ => 0,
            },
            shrink: net.map_or(0.0, |c| c.shrink),
            gate: net.map_or(0.0, |c| c.gate),
            gain: net.is_some_and(|c| c.gain) as u32,
            agree: net.map_or(0.0, |c| c.agree),
        }
    }

    /// Chooses the frame's active views (`self.active`). With more views than `culling.above`
    /// this renders the G-buffer and the view culling pass in a submission of their own and
    /// reads the pass back (returns true: the G-buffer is done).
    fn cull_views(&mut self, cam: &Camera, timer: Option<&mut Timer>) -> Result<bool> {
        let n = self.scene.data.cameras.len();
        if !self.culling.needed(n, self.exclude) {
            self.active = (0..n as u32).filter(|&i| Some(i) != self.exclude).collect();
            return Ok(false);
        }
        let (seen, points) = self.view_visibility(cam, timer)?;
        let cameras = &self.scene.data.cameras;
        self.active = view_cull::choose(
            &self.culling,
            &seen,
            &points,
            cameras,
            cam.center(),
            self.exclude,
        );
        Ok(true)
    }

    /// Renders `cam`'s G-buffer and the view culling pass; returns its visibility bits and grid
    /// points (as [`view_cull::reference`]). Call after `buffers` for `cam`'s size.
    pub fn view_visibility(
        &self,
        cam: &Camera,
        timer: Option<&mut Timer>,
    ) -> Result<(Vec<u32>, Vec<[f32; 4]>)> {
        let b = self.last()?;
        let n = self.scene.data.cameras.len();
        let grid = view_cull::grid(cam.width, cam.height);
        let nw = view_cull::words(grid) as u32;
        let push = view_cull::Push {
            eye: cam.center().extend(1.0).into(),
            width: cam.width,
            height: cam.height,
            grid_w: grid.0,
            grid_h: grid.1,
            nviews: n as u32,
            view_w: self.scene.views.width,
            view_h: self.scene.views.height,
            words: nw,
        };
        let gpu = self.gpu.clone();
        let res = gpu.submit(|cmd| -> Result<BarrierCount> {
            let mut g = Graph::new(&gpu, cmd, timer);
            self.resources(&mut g, b);
            self.record_gbuffer(&mut g, b, cam)?;
            let threads = (nw * n as u32, 1, 1);
            g.dispatch("view culling", &self.view_cull, bytes_of(&push), threads)?;
            Ok(g.barriers)
        })?;
        self.add_barriers(&res?);
        let mut seen: Vec<u32> = bytemuck::pod_collect_to_vec(&b.cull_seen.download()?);
        let mut points: Vec<[f32; 4]> = b.cull_points.download_vec()?;
        seen.truncate(nw as usize * n);
        points.truncate((grid.0 * grid.1) as usize);
        Ok((seen, points))
    }

    fn record_gbuffer<'a>(
        &'a self,
        g: &mut Graph<'a, '_>,
        b: &'a FrameBuffers,
        cam: &Camera,
    ) -> Result<()> {
        let mesh = &self.scene.mesh;
        g.external("g-buffer", &[], &GBUFFER, |cmd| {
            self.gbuffer.record(cmd, mesh, cam, NEAR, FAR, &b.gbuf)
        })
    }

    /// The active views of the last frame, ascending (what its composites read).
    pub fn active_views(&self) -> &[u32] {
        &self.active
    }

    /// The frame's resources by the names its shaders give them.
    fn resources<'a>(&'a self, g: &mut Graph<'a, '_>, b: &'a FrameBuffers) {
        let s = &self.scene;
        let sm = s.sampler.raw;
        let net_out = b.net.as_ref().map(|n| &n.out).unwrap_or(&b.dummy_net_out);
        let (live_caches, live_corners, live_lights) = self.live.buffers();
        let (name, views) = s.views.bind();
        g.set(name, views)
            .set("g_pos", Bind::StorageImage(&b.gbuf.pos_depth))
            .set("g_nrm", Bind::StorageImage(&b.gbuf.normal))
            .set("g_tri", Bind::StorageImage(&b.gbuf.tri))
            .set("Active", Bind::Buffer(&b.active))
            .set("NovelCamera", Bind::Buffer(&b.camera))
            .set("CullSeen", Bind::Buffer(&b.cull_seen))
            .set("CullPoints", Bind::Buffer(&b.cull_points))
            .set("tex_img", Bind::Sampled(&s.maps.img, sm))
            .set("tex_msrc", Bind::Sampled(&s.maps.msrc, sm))
            .set("tex_esrc", Bind::Sampled(&s.maps.esrc, sm))
            .set("tex_eadd", Bind::Sampled(&s.maps.eadd, sm))
            .set("Intensity", Bind::Buffer(&b.intensity))
            .set("Keep", Bind::Buffer(&b.keep))
            .set("tlas", Bind::Accel(s.mesh.tlas.raw))
            .set("Comp", Bind::Buffer(&b.comp))
            .set("ViewsSeen", Bind::Buffer(&b.views_seen))
            .set("Irr", Bind::Buffer(&b.irr))
            .set("Mirror", Bind::Buffer(&b.mirror))
            .set("Glossy", Bind::Buffer(&b.glossy))
            .set("GlossySums", Bind::Buffer(&b.glossy_sums))
            .set(
                "GlossyFit",
                Bind::Buffer(self.glossy_fit.as_ref().map_or(&self.zero_fit, |f| &f.1)),
            )
            .set("NetIn", Bind::Buffer(&b.input.buf))
            .set("NetOut", Bind::Buffer(&net_out.buf))
            .set("Hdr", Bind::Buffer(&b.hdr))
            .set("Ldr", Bind::Buffer(&b.ldr))
            .set("Emitters", Bind::Buffer(&s.emitter_buf))
            .set("Originals", Bind::Buffer(&s.original_buf))
            .set(
                "SightTris",
                Bind::Buffer(self.sight_pass.as_ref().map_or(&self.zero_fit, |p| &p.tris)),
            )
            .set(
                "SightVis",
                Bind::Buffer(self.sight.as_ref().map_or(&self.zero_fit, |c| &c.vis)),
            )
            .set("SightCols", Bind::Buffer(&b.sight_cols))
            .set("LiveVerts", Bind::Buffer(&s.mesh.positions))
            .set("LiveIndices", Bind::Buffer(&s.mesh.indices))
            .set("LiveCaches", Bind::Buffer(live_caches))
            .set("LiveCorners", Bind::Buffer(live_corners))
            .set("Lives", Bind::Buffer(live_lights));
    }

    /// The buffers of the last [`Renderer::render`] (composites: [`FrameBuffers::composites`]).
    pub fn buffers_ref(&self) -> Option<&FrameBuffers> {
        self.bufs.first()
    }

    /// Linear RGB of the last frame.
    pub fn hdr(&self) -> Result<Vec<[f32; 4]>> {
        let b = self.last()?;
        let mut v: Vec<[f32; 4]> = b.hdr.download_vec()?;
        v.truncate((b.width * b.height) as usize);
        Ok(v)
    }

    /// Display RGBA8 of the last frame.
    pub fn ldr(&self) -> Result<Vec<u8>> {
        let b = self.last()?;
        let n = (b.width * b.height * 4) as u64;
        b.ldr.download_range(0, n)
    }

    fn last(&self) -> Result<&FrameBuffers> {
        self.bufs
            .first()
            .ok_or_else(|| Error::Other("no frame rendered yet".into()))
    }
}
