//! The input views on the GPU for the bake: cameras, G-buffers of the proxy mesh from each
//! view (the per-view depth maps of §4.1, used by every visibility test), and the colour images,
//! view-major in storage buffers (`shaders_glsl/common/views.glsl`).

use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::error::{Error, Result};
use crate::gpu::{vk, Bind, Buffer, Gpu, MemoryLocation, RayScene};
use crate::raster::GbufferPass;
use crate::scene::{Camera, GpuCamera, Photo, RgbImage};

/// Near and far planes of the per-view depth maps (m).
pub const NEAR: f32 = 0.02;
pub const FAR: f32 = 1000.0;

/// Host copy of the views (the CPU references read this).
pub struct ViewData {
    pub cameras: Vec<Camera>,
    pub width: u32,
    pub height: u32,
    /// Per view and pixel: world position and camera depth (w = 0: no surface).
    pub pos: Vec<[f32; 4]>,
    pub nrm: Vec<[f32; 4]>,
    /// Per view and pixel: linear RGB radiance; w = 1, or 0 where the photo clipped (a lower
    /// bound, not radiance: the gathers leave it out, `clipped` in views.glsl).
    pub img: Vec<[f32; 4]>,
    /// Per view and pixel: proxy triangle id + 1 (0: none).
    pub tri: Vec<u32>,
}

/// A photo as the views hold it: linear RGB, w = 1, or 0 where the photo clipped.
pub fn photo_rgba(photo: &Photo) -> impl Iterator<Item = [f32; 4]> + '_ {
    let clipped = |i: usize| photo.clipped.get(i).copied().unwrap_or(false);
    (photo.image.pixels.iter().enumerate())
        .map(move |(i, p)| [p[0], p[1], p[2], if clipped(i) { 0.0 } else { 1.0 }])
}

impl ViewData {
    /// Rasterizes the proxy mesh from every camera and gathers the images.
    pub fn build(
        gpu: &Arc<Gpu>,
        mesh: &RayScene,
        cameras: &[Camera],
        images: &[RgbImage],
    ) -> Result<ViewData> {
        ViewData::build_with(gpu, mesh, cameras, |j, img| {
            img.extend(images[j].pixels.iter().map(|p| [p[0], p[1], p[2], 1.0]))
        })
    }

    /// `build` from the scene's photos (no copy of their images), their clipped pixels marked.
    pub fn from_photos(
        gpu: &Arc<Gpu>,
        mesh: &RayScene,
        cameras: &[Camera],
        photos: &[Photo],
    ) -> Result<ViewData> {
        ViewData::build_with(gpu, mesh, cameras, |j, img| {
            img.extend(photo_rgba(&photos[j]))
        })
    }

    /// `build` with view `j`'s image appended by `image(j, img)` as RGBA (w = 1): the frame
    /// hands over its RGBA layers without another copy of every view.
    pub fn build_with(
        gpu: &Arc<Gpu>,
        mesh: &RayScene,
        cameras: &[Camera],
        mut image: impl FnMut(usize, &mut Vec<[f32; 4]>),
    ) -> Result<ViewData> {
        let pass = GbufferPass::new(gpu)?;
        let mut d = ViewData::cameras_only(cameras)?;
        for (j, c) in cameras.iter().enumerate() {
            let g = pass.render(mesh, c, NEAR, FAR)?.download()?;
            d.pos.extend(g.pos_depth);
            d.nrm.extend(g.normal);
            d.tri.extend(g.tri);
            image(j, &mut d.img);
        }
        Ok(d)
    }

    /// The views' cameras and their one image size, no pixels yet.
    fn cameras_only(cameras: &[Camera]) -> Result<ViewData> {
        let (width, height) = one_size(cameras)?;
        Ok(ViewData {
            cameras: cameras.to_vec(),
            width,
            height,
            pos: vec![],
            nrm: vec![],
            img: vec![],
            tri: vec![],
        })
    }

    pub fn pixels(&self) -> usize {
        (self.width * self.height) as usize
    }

    /// Whether global pixel `q` clipped in its photo.
    pub fn clipped(&self, q: usize) -> bool {
        self.img[q][3] <= 0.0
    }

    /// CPU mirror of `visible_pixel` in views.glsl: the global pixel index where view `j`
    /// sees `p`, if it does.
    pub fn visible_pixel(&self, j: usize, p: Vec3) -> Option<usize> {
        let c = &self.cameras[j];
        let q = c.to_camera(p);
        if q.z <= 1e-3 {
            return None;
        }
        let px = Vec2::new(c.fx * q.x / q.z + c.cx, c.fy * q.y / q.z + c.cy);
        if px.x < 0.0 || px.y < 0.0 || px.x >= self.width as f32 || px.y >= self.height as f32 {
            return None;
        }
        let idx = j * self.pixels() + px.y as usize * self.width as usize + px.x as usize;
        let d = self.pos[idx][3];
        (d > 0.0 && (d - q.z).abs() <= DEPTH_EPS * q.z).then_some(idx)
    }

    /// CPU mirror of `best_view` in views.glsl.
    pub fn best_view(&self, y: Vec3, dir: Vec3, exclude: usize) -> Option<usize> {
        let mut best = (-2.0f32, None);
        for j in 0..self.cameras.len() {
            if j == exclude {
                continue;
            }
            if let Some(q) = self.visible_pixel(j, y) {
                let c = (y - self.cameras[j].center()).normalize().dot(dir);
                if c > best.0 {
                    best = (c, Some(q));
                }
            }
        }
        best.1
    }
}

pub use crate::constants::DEPTH_EPS;

/// The views' buffers on the GPU. Shaders read them through device addresses (views.glsl), which
/// one small uniform buffer, `addresses`, holds: no binding grows with the capture.
pub struct GpuViews {
    pub addresses: Buffer,
    pub cameras: Buffer,
    pub pos: Buffer,
    pub nrm: Buffer,
    pub img: Buffer,
    /// Per view and pixel: proxy triangle id + 1 (0: none).
    pub tri: Buffer,
    pub count: u32,
    pub width: u32,
    pub height: u32,
}

/// Read through device addresses only (views.glsl): no descriptor binds them, so
/// maxStorageBufferRange does not bound the views' count or size.
const BY_ADDRESS: vk::BufferUsageFlags = vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;

impl GpuViews {
    pub fn upload(gpu: &Arc<Gpu>, d: &ViewData) -> Result<GpuViews> {
        let maps = [
            Buffer::from_slice(gpu, "view positions", BY_ADDRESS, &d.pos)?,
            Buffer::from_slice(gpu, "view normals", BY_ADDRESS, &d.nrm)?,
            Buffer::from_slice(gpu, "view images", BY_ADDRESS, &d.img)?,
        ];
        let tri = Buffer::from_slice(gpu, "view triangles", BY_ADDRESS, &d.tri)?;
        GpuViews::assemble(gpu, d, maps, tri)
    }

    /// The views straight onto the device, one at a time: each view's G-buffer and its image
    /// (`image(j)`, RGBA, loaded when asked for) go to their place in the device buffers, so no
    /// host copy of all views is ever held (the frame and the bake; the CPU references keep
    /// [`ViewData`]'s). The `ViewData` returned holds the cameras only.
    pub fn build_streamed(
        gpu: &Arc<Gpu>,
        mesh: &RayScene,
        cameras: &[Camera],
        mut image: impl FnMut(usize) -> Result<Vec<[f32; 4]>>,
    ) -> Result<(ViewData, GpuViews)> {
        let (width, height) = one_size(cameras)?;
        let (n, nv) = ((width * height) as u64, cameras.len() as u64);
        let new = |name: &str, bytes: u64, usage| {
            Buffer::new(gpu, name, nv * n * bytes, usage, MemoryLocation::GpuOnly)
        };
        let maps = [
            new("view positions", 16, BY_ADDRESS)?,
            new("view normals", 16, BY_ADDRESS)?,
            new("view images", 16, BY_ADDRESS)?,
        ];
        let tri = new("view triangles", 4, BY_ADDRESS)?;
        let pass = GbufferPass::new(gpu)?;
        for (j, c) in cameras.iter().enumerate() {
            let g = pass.render(mesh, c, NEAR, FAR)?.download()?;
            let at = |bytes: u64| j as u64 * n * bytes;
            maps[0].upload_at(at(16), bytemuck::cast_slice(&g.pos_depth))?;
            maps[1].upload_at(at(16), bytemuck::cast_slice(&g.normal))?;
            maps[2].upload_at(at(16), bytemuck::cast_slice(&image(j)?))?;
            tri.upload_at(at(4), bytemuck::cast_slice(&g.tri))?;
        }
        let d = ViewData::cameras_only(cameras)?;
        let views = GpuViews::assemble(gpu, &d, maps, tri)?;
        Ok((d, views))
    }

    /// The views' buffers with their cameras and the uniform block of their addresses.
    fn assemble(
        gpu: &Arc<Gpu>,
        d: &ViewData,
        [pos, nrm, img]: [Buffer; 3],
        tri: Buffer,
    ) -> Result<GpuViews> {
        let cams: Vec<GpuCamera> = d.cameras.iter().map(|c| c.to_gpu(NEAR, FAR)).collect();
        let cameras = Buffer::from_slice(gpu, "view cameras", BY_ADDRESS, &cams)?;
        let addresses: Vec<u64> = [&cameras, &pos, &nrm, &img, &tri]
            .iter()
            .map(|b| b.address)
            .collect();
        Ok(GpuViews {
            addresses: Buffer::from_slice(
                gpu,
                "view addresses",
                vk::BufferUsageFlags::UNIFORM_BUFFER,
                &addresses,
            )?,
            cameras,
            pos,
            nrm,
            img,
            tri,
            count: d.cameras.len() as u32,
            width: d.width,
            height: d.height,
        })
    }

    /// The resource views.glsl declares (its `Views` block).
    pub fn bind(&self) -> (&'static str, Bind<'_>) {
        ("Views", Bind::Buffer(&self.addresses))
    }
}

/// The views' one image size (the bake and the frame need all views at one resolution).
fn one_size(cameras: &[Camera]) -> Result<(u32, u32)> {
    let (width, height) = (cameras[0].width, cameras[0].height);
    match (cameras.iter()).find(|c| (c.width, c.height) != (width, height)) {
        Some(c) => Err(Error::Other(format!(
            "the bake needs all views at one resolution: {}x{} and {}x{}",
            width, height, c.width, c.height
        ))),
        None => Ok((width, height)),
    }
}

/// Runs a pass that writes one vec4 per pixel of a view into `out` and reads it back.
pub fn run_pixels(
    gpu: &Arc<Gpu>,
    views: &GpuViews,
    record: impl FnOnce(vk::CommandBuffer, &Buffer) -> Result<()>,
) -> Result<Vec<[f32; 4]>> {
    run_items(gpu, views.width * views.height, record)
}

/// Runs a pass that writes one vec4 per mesh vertex into `out` and reads it back.
pub fn run_vertices(
    gpu: &Arc<Gpu>,
    nverts: u32,
    record: impl FnOnce(vk::CommandBuffer, &Buffer) -> Result<()>,
) -> Result<Vec<[f32; 4]>> {
    run_items(gpu, nverts, record)
}

/// Runs a pass that writes `n` vec4s into `out` and reads them back.
fn run_items(
    gpu: &Arc<Gpu>,
    n: u32,
    record: impl FnOnce(vk::CommandBuffer, &Buffer) -> Result<()>,
) -> Result<Vec<[f32; 4]>> {
    let out = Buffer::new(
        gpu,
        "pass out",
        n.max(1) as u64 * 16,
        vk::BufferUsageFlags::STORAGE_BUFFER,
        crate::gpu::MemoryLocation::GpuOnly,
    )?;
    let mut res = Ok(());
    gpu.submit(|cmd| res = record(cmd, &out))?;
    res?;
    let mut v: Vec<[f32; 4]> = out.download_vec()?;
    v.truncate(n as usize);
    Ok(v)
}

/// Camera centre of view `j`, oriented normal at a pixel (facing that view's camera).
pub fn facing_normal(d: &ViewData, gi: usize, view: usize) -> Vec3 {
    let x = Vec3::from_slice(&d.pos[gi][..3]);
    let n = Vec3::from_slice(&d.nrm[gi][..3]);
    if n.dot(d.cameras[view].center() - x) < 0.0 {
        -n
    } else {
        n
    }
}
