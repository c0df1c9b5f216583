//! An interactive window over the city (feature `window`): winit 0.30 + a wgpu surface.
//!
//! Every frame the viewer culls the blocks as the walk does ([`CullStep`]: one spatial structure,
//! frustum culling as Willmott et al., §2 and Pina, Serón and Cerezo, §4 describe it, optionally
//! through the occlusion culler's occluder shadows and cull map, Willmott et al., §3), draws the
//! survivors with [`MeshRenderer`] and shows the image in the window.
//!
//! With a far field ([`ViewerScene::far`]) the frame is the walk's hybrid frame instead: the
//! walk's [`FarStep`] picks, coarse to fine and front to back, the nodes whose projected error
//! is at most τ (Cignoni et al., §4; Di Benedetto, §4.4) and the blocks left to draw as meshes;
//! the meshes are drawn first and the far field is ray-cast into the same colour and depth
//! targets ([`FarRenderer`]: BlockMaps or relief impostors), as `blockwalk walk --far blockmaps`
//! (or `--far relief`) draws it.
//!
//! When the scene has a terrain (`Scene::terrain`), its tiles are uploaded with the meshes and
//! each frame draws the terrain's cut for the camera, depth-tested before the meshes and the far
//! field, instead of the flat ground ([`crate::visibility::draws_flat_ground`]).
//!
//! The frame is drawn by the same [`MeshRenderer`] as the headless tools (so what the window shows
//! is exactly what `blockwalk walk --render` writes), read back and written into the surface
//! texture with `Queue::write_texture`, swapping red and blue for `Bgra8` surfaces. This costs a
//! read-back per frame, which keeps the renderer unchanged and is fine at window sizes.
//!
//! Controls: WASD or arrow keys move, dragging with the left mouse button looks around, Q/E or
//! PageDown/PageUp move down/up, Shift moves five times faster, P plays or pauses the route (the
//! camera then follows [`CameraRoute::camera_at`]), Esc quits. The title shows frames per
//! second, blocks and triangles drawn, and the structure.
//!
//! ## Non-interactive check
//! [`ViewerOptions::screenshot`] renders [`ViewerOptions::frames`] frames evenly along the route,
//! saves the last one as PNG and closes the window. Without a display, under Xvfb with the
//! lavapipe software Vulkan driver:
//!
//! ```text
//! NODEVICE_SELECT=1 WGPU_BACKEND=vulkan xvfb-run -s "-screen 0 1280x720x24" \
//!   cargo run --features window -- view data/bubenec/buildings.shp \
//!   --streets data/bubenec/streets.shp --route orbit --frames 3 --screenshot view.png
//! ```

use super::blockmap::FarReadback;
use super::frames::FarRenderer;
use super::{Gpu, MeshRenderer, RenderError, RenderOptions};
use crate::blockmap::SelectOptions;
use crate::blocks::BlockId;
use crate::city::Mesh;
use crate::geom::Camera;
use crate::index::Structure;
use crate::route::CameraRoute;
use crate::scene::Scene;
use crate::walk::{CullMode, CullStep, FarField, FarStep};
use glam::DVec3;
use std::collections::HashSet;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{KeyCode, PhysicalKey};
use winit::window::{Window, WindowId};

/// What can go wrong in the viewer. Failures of winit and wgpu keep their error as the
/// [`source`](std::error::Error::source).
#[derive(Debug, thiserror::Error)]
pub enum WindowError {
    /// The requested window size has no pixels.
    #[error("window size {width}x{height} is empty")]
    EmptyWindow {
        /// Width asked for, pixels.
        width: u32,
        /// Height asked for, pixels.
        height: u32,
    },
    /// Neither `DISPLAY` nor `WAYLAND_DISPLAY` is set (Linux and the BSDs): there is nothing to
    /// open a window on.
    #[error(
        "no display found: set DISPLAY (X11) or WAYLAND_DISPLAY, run under xvfb-run, or use \
         `blockwalk walk --render` for headless frames"
    )]
    NoDisplay,
    /// The event loop could not be created or failed (usually: no X11 or Wayland display).
    #[error(
        "cannot open a window (no usable display? set DISPLAY, run under xvfb-run, or use \
         `blockwalk walk --render` for headless frames)"
    )]
    EventLoop {
        /// What winit said.
        #[source]
        source: winit::error::EventLoopError,
    },
    /// The window could not be created.
    #[error("cannot create the window (is a display available? try xvfb-run)")]
    CreateWindow {
        /// What winit said.
        #[source]
        source: winit::error::OsError,
    },
    /// The GPU side failed (no adapter, device, read-back).
    #[error(transparent)]
    Render(#[from] RenderError),
    /// wgpu could not make a surface for the window.
    #[error("window surface: {source}")]
    CreateSurface {
        /// What wgpu said.
        #[source]
        source: wgpu::CreateSurfaceError,
    },
    /// The surface cannot be written to by a copy, which the viewer needs.
    #[error("window surface: the surface on {adapter} cannot be written to (usages {usages:?})")]
    SurfaceNotWritable {
        /// Adapter name and backend.
        adapter: String,
        /// The usages the surface offers.
        usages: wgpu::TextureUsages,
    },
    /// The surface offers no 8-bit RGBA or BGRA format.
    #[error("window surface: no 8-bit RGBA/BGRA surface format among {formats:?}")]
    NoSurfaceFormat {
        /// The formats it offers.
        formats: Vec<wgpu::TextureFormat>,
    },
    /// The adapter cannot present to the surface.
    #[error("window surface: surface not supported by {adapter}")]
    SurfaceUnsupported {
        /// Adapter name and backend.
        adapter: String,
    },
    /// Acquiring the next surface texture raised a validation error.
    #[error("window surface: validation error acquiring a frame")]
    AcquireFrame,
    /// The scene lacks what the viewer was asked to use.
    #[error("viewer scene: {0}")]
    Scene(String),
    /// The screenshot could not be written.
    #[error("screenshot {path}: {source}")]
    Screenshot {
        /// Where it should have gone.
        path: PathBuf,
        /// Why it failed.
        #[source]
        source: RenderError,
    },
}

/// What the viewer shows.
pub struct ViewerScene {
    /// The scene (its meshes are uploaded once).
    pub scene: Scene,
    /// The structure that frustum-culls the blocks (built in the scene).
    pub structure: Structure,
    /// Cull through the scene's occlusion culler as well (it must have one).
    pub occlusion: bool,
    /// The route that P plays (and the start pose).
    pub route: CameraRoute,
    /// Far field: BlockMaps drawn where their projected error is at most τ.
    pub far: Option<ViewerFar>,
}

/// The far field of the viewer and the selection settings.
pub struct ViewerFar {
    /// The far field (built for the scene's blocks), e.g. a BlockMap tree.
    pub field: Box<dyn FarField + Send>,
    /// τ and hysteresis.
    pub select: SelectOptions,
}

impl std::fmt::Debug for ViewerFar {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewerFar")
            .field("field", &self.field.name())
            .field("nodes", &self.field.len())
            .field("select", &self.select)
            .finish()
    }
}

impl std::fmt::Debug for ViewerScene {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewerScene")
            .field("scene", &self.scene)
            .field("structure", &self.structure)
            .field("occlusion", &self.occlusion)
            .field("route", &self.route.name)
            .field("far", &self.far)
            .finish()
    }
}

/// Window size and the non-interactive mode.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// Initial window width, pixels.
    pub width: u32,
    /// Initial window height, pixels.
    pub height: u32,
    /// When set: render [`Self::frames`] frames along the route, save the last as PNG here, quit.
    pub screenshot: Option<PathBuf>,
    /// Frames along the route in screenshot mode (at least 1).
    pub frames: usize,
    /// Base flying speed, metres per second (Shift: five times).
    pub speed: f64,
}

impl Default for ViewerOptions {
    /// 1280 × 720, interactive, 30 frames for a screenshot, 20 m/s.
    fn default() -> Self {
        Self {
            width: 1280,
            height: 720,
            screenshot: None,
            frames: 30,
            speed: 20.0,
        }
    }
}

/// What a viewer session did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct ViewerSummary {
    /// Frames shown.
    pub frames: usize,
    /// Mean frames per second over the session.
    pub fps: f64,
    /// Blocks drawn in the last frame.
    pub blocks: u32,
    /// Triangles drawn in the last frame.
    pub triangles: u64,
    /// Maps drawn in the last frame (0 without a far field).
    pub far_nodes: usize,
    /// Mean maps drawn per frame over the session.
    pub far_nodes_mean: f64,
    /// Pixels the maps won in the last frame.
    pub far_pixels: u64,
    /// Adapter used.
    pub adapter: String,
    /// The screenshot written, if any.
    pub screenshot: Option<PathBuf>,
}

/// False where a window needs `DISPLAY` or `WAYLAND_DISPLAY` and neither is set (a free
/// desktop Unix); true elsewhere (Windows and macOS always have their window server).
pub(crate) fn display_available() -> bool {
    if cfg!(any(
        target_os = "windows",
        target_os = "macos",
        target_os = "ios"
    )) {
        return true;
    }
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// Opens the window and runs until it is closed (or the screenshot is written).
pub fn run_viewer(
    scene: ViewerScene,
    options: ViewerOptions,
) -> Result<ViewerSummary, WindowError> {
    if options.width == 0 || options.height == 0 {
        return Err(WindowError::EmptyWindow {
            width: options.width,
            height: options.height,
        });
    }
    let culler = scene.scene.occlusion.as_ref().filter(|_| scene.occlusion);
    let far_step = match &scene.far {
        Some(f) => Some(FarStep::new(
            f.field
                .selector(&scene.scene.bounds, f.select)
                .map_err(|e| WindowError::Scene(format!("far field: {e}")))?,
            culler,
        )),
        None => None,
    };
    let cull = CullStep::new(&scene.scene);
    if !display_available() {
        return Err(WindowError::NoDisplay);
    }
    let event_loop = EventLoop::new().map_err(|source| WindowError::EventLoop { source })?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut camera = scene.route.camera_at(scene.route.start());
    camera.aspect = options.width as f64 / options.height as f64;
    let mut app = App {
        controls: Controls::new(options.screenshot.is_some()),
        scene,
        options,
        state: None,
        error: None,
        camera,
        route_t: 0.0,
        last_tick: Instant::now(),
        started: Instant::now(),
        title: FpsTitle::new(),
        visible: Vec::new(),
        far: Vec::new(),
        far_step,
        cull,
        far_total: 0,
        summary: ViewerSummary::default(),
    };
    app.route_t = app.scene.route.start();
    event_loop
        .run_app(&mut app)
        .map_err(|source| WindowError::EventLoop { source })?;
    if let Some(e) = app.error {
        return Err(e);
    }
    if app.summary.frames > 0 {
        app.summary.far_nodes_mean = app.far_total as f64 / app.summary.frames as f64;
    }
    let secs = app.started.elapsed().as_secs_f64();
    app.summary.fps = if secs > 0.0 {
        app.summary.frames as f64 / secs
    } else {
        0.0
    };
    Ok(app.summary)
}

/// A window with a wgpu surface that frames are copied into: the instance with the window's
/// display, an adapter able to present to it, its device, an 8-bit RGBA or BGRA format.
pub(crate) struct WindowSurface {
    pub(crate) window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    pub(crate) config: wgpu::SurfaceConfiguration,
    pub(crate) gpu: Gpu,
    /// Swap red and blue when writing into the surface.
    bgra: bool,
}

impl WindowSurface {
    /// Opens a window titled `title` of `width × height` pixels and its surface.
    pub(crate) fn open(
        event_loop: &ActiveEventLoop,
        title: String,
        width: u32,
        height: u32,
    ) -> Result<Self, WindowError> {
        let attrs = Window::default_attributes()
            .with_title(title)
            .with_inner_size(PhysicalSize::new(width, height));
        let window = Arc::new(
            event_loop
                .create_window(attrs)
                .map_err(|source| WindowError::CreateWindow { source })?,
        );
        let instance = wgpu::Instance::new(
            wgpu::InstanceDescriptor::new_with_display_handle_from_env(Box::new(window.clone())),
        );
        let surface = instance
            .create_surface(window.clone())
            .map_err(|source| WindowError::CreateSurface { source })?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: Some(&surface),
            apply_limit_buckets: false,
        }))
        .map_err(|source| RenderError::NoAdapter { source })?;
        let gpu = Gpu::from_adapter(adapter)?;
        let caps = surface.get_capabilities(&gpu.adapter);
        if !caps.usages.contains(wgpu::TextureUsages::COPY_DST) {
            return Err(WindowError::SurfaceNotWritable {
                adapter: gpu.adapter_name(),
                usages: caps.usages,
            });
        }
        // Frames are plain (non-sRGB) RGBA8: take a surface format with the same bytes.
        let (format, bgra) = [
            (wgpu::TextureFormat::Rgba8Unorm, false),
            (wgpu::TextureFormat::Bgra8Unorm, true),
            (wgpu::TextureFormat::Rgba8UnormSrgb, false),
            (wgpu::TextureFormat::Bgra8UnormSrgb, true),
        ]
        .into_iter()
        .find(|(f, _)| caps.formats.contains(f))
        .ok_or_else(|| WindowError::NoSurfaceFormat {
            formats: caps.formats.clone(),
        })?;
        let size = window.inner_size();
        let (width, height) = (size.width.max(1), size.height.max(1));
        let mut config = surface
            .get_default_config(&gpu.adapter, width, height)
            .ok_or_else(|| WindowError::SurfaceUnsupported {
                adapter: gpu.adapter_name(),
            })?;
        config.format = format;
        config.usage = wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_DST;
        config.present_mode = wgpu::PresentMode::Fifo;
        surface.configure(&gpu.device, &config);
        Ok(Self {
            window,
            surface,
            config,
            gpu,
            bgra,
        })
    }

    /// What a viewer does when its window has opened: the camera takes the window's aspect,
    /// the summary its adapter, and the first frame is asked for.
    pub(crate) fn opened(&self, camera: &mut Camera, summary: &mut ViewerSummary) {
        let size = self.window.inner_size();
        camera.aspect = size.width.max(1) as f64 / size.height.max(1) as f64;
        summary.adapter = self.gpu.adapter_name();
        self.window.request_redraw();
    }

    /// The surface at `width × height`.
    pub(crate) fn reconfigure(&mut self, width: u32, height: u32) {
        self.config.width = width;
        self.config.height = height;
        self.surface.configure(&self.gpu.device, &self.config);
    }

    /// Copies `rgba` (`width × height`, RGBA8) into the next surface texture and presents it
    /// (a frame of another size than the surface's is not copied). Returns false when no frame
    /// could be shown this time (timeout, occluded, the surface outdated and reconfigured).
    pub(crate) fn show(&self, rgba: &[u8], width: u32, height: u32) -> Result<bool, WindowError> {
        let texture = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(false);
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.gpu.device, &self.config);
                return Ok(false);
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(WindowError::AcquireFrame);
            }
        };
        let tex_size = texture.texture.size();
        if tex_size.width == width && tex_size.height == height {
            let mut bytes = rgba.to_vec();
            if self.bgra {
                for p in bytes.chunks_exact_mut(4) {
                    p.swap(0, 2);
                }
            }
            self.gpu.queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture.texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                &bytes,
                wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(width * 4),
                    rows_per_image: Some(height),
                },
                tex_size,
            );
            self.gpu.queue.submit([]);
        }
        self.gpu.queue.present(texture);
        Ok(true)
    }
}

/// Advances the route's clock `t` by `dt` while the route plays (looping), or in screenshot mode
/// puts it at frame `shown` of the options' frames spread evenly over the route; returns true
/// when the camera follows the route.
pub(crate) fn route_time(
    route: &CameraRoute,
    options: &ViewerOptions,
    controls: &Controls,
    shown: usize,
    dt: f64,
    t: &mut f64,
) -> bool {
    if options.screenshot.is_some() {
        let n = options.frames.max(1);
        let i = shown.min(n - 1);
        let f = if n > 1 {
            i as f64 / (n - 1) as f64
        } else {
            0.0
        };
        *t = route.start() + route.duration() * f;
        true
    } else if controls.playing {
        *t += dt;
        if *t > route.start() + route.duration() {
            *t = route.start();
        }
        true
    } else {
        false
    }
}

/// Frames per second for the window's title, measured over half a second at least.
#[derive(Debug)]
pub(crate) struct FpsTitle {
    at: Instant,
    frames: usize,
}

impl FpsTitle {
    /// Counting from now.
    pub(crate) fn new() -> Self {
        Self {
            at: Instant::now(),
            frames: 0,
        }
    }

    /// Counts a frame shown; every half second or more, the frames per second since the last
    /// time (then the title is due).
    pub(crate) fn frame(&mut self) -> Option<f64> {
        self.frames += 1;
        let since = self.at.elapsed().as_secs_f64();
        (since >= 0.5).then(|| {
            let fps = self.frames as f64 / since;
            *self = Self::new();
            fps
        })
    }
}

/// The viewer's controls: keys held, the mouse drag, and whether the route plays.
#[derive(Debug, Default)]
pub(crate) struct Controls {
    keys: HashSet<KeyCode>,
    dragging: bool,
    last_cursor: Option<(f64, f64)>,
    /// The camera follows the route.
    pub(crate) playing: bool,
}

impl Controls {
    /// Controls with the route playing or not.
    pub(crate) fn new(playing: bool) -> Self {
        Self {
            playing,
            ..Self::default()
        }
    }

    /// Handles a keyboard or mouse event (keys held, P, dragging to look around with
    /// `camera`); returns true for Esc.
    pub(crate) fn input(&mut self, event: &WindowEvent, camera: &mut Camera) -> bool {
        match event {
            WindowEvent::KeyboardInput { event, .. } => {
                let PhysicalKey::Code(code) = event.physical_key else {
                    return false;
                };
                match event.state {
                    ElementState::Pressed => {
                        if code == KeyCode::Escape {
                            return true;
                        } else if code == KeyCode::KeyP && !event.repeat {
                            self.playing = !self.playing;
                            if !self.playing {
                                // Keep flying from where the route left the camera.
                                self.last_cursor = None;
                            }
                        }
                        self.keys.insert(code);
                    }
                    ElementState::Released => {
                        self.keys.remove(&code);
                    }
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Left,
                ..
            } => {
                self.dragging = *state == ElementState::Pressed;
                if !self.dragging {
                    self.last_cursor = None;
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                if self.dragging && !self.playing {
                    if let Some((x, y)) = self.last_cursor {
                        let k = 0.004;
                        camera.yaw -= (position.x - x) * k;
                        camera.pitch = (camera.pitch - (position.y - y) * k).clamp(-1.55, 1.55);
                    }
                }
                self.last_cursor = Some((position.x, position.y));
            }
            _ => {}
        }
        false
    }

    /// Moves `camera` by the keys held for `dt` seconds at `speed` metres per second (Shift:
    /// five times).
    pub(crate) fn fly(&self, camera: &mut Camera, speed: f64, dt: f64) {
        let held = |k: &[KeyCode]| k.iter().any(|k| self.keys.contains(k));
        let fast = held(&[KeyCode::ShiftLeft, KeyCode::ShiftRight]);
        let speed = speed * if fast { 5.0 } else { 1.0 };
        let (s, c) = camera.yaw.sin_cos();
        let ahead = DVec3::new(c, s, 0.0);
        let right = DVec3::new(s, -c, 0.0);
        let mut d = DVec3::ZERO;
        if held(&[KeyCode::KeyW, KeyCode::ArrowUp]) {
            d += ahead;
        }
        if held(&[KeyCode::KeyS, KeyCode::ArrowDown]) {
            d -= ahead;
        }
        if held(&[KeyCode::KeyD, KeyCode::ArrowRight]) {
            d += right;
        }
        if held(&[KeyCode::KeyA, KeyCode::ArrowLeft]) {
            d -= right;
        }
        if held(&[KeyCode::KeyE, KeyCode::PageUp]) {
            d.z += 1.0;
        }
        if held(&[KeyCode::KeyQ, KeyCode::PageDown]) {
            d.z -= 1.0;
        }
        if d != DVec3::ZERO {
            camera.position += d.normalize() * speed * dt;
        }
    }
}

/// GPU objects tied to the window.
struct GpuState {
    surf: WindowSurface,
    renderer: MeshRenderer,
    /// The far field on the GPU, when the scene has one.
    far: Option<FarRenderer>,
}

impl std::ops::Deref for GpuState {
    type Target = WindowSurface;
    fn deref(&self) -> &WindowSurface {
        &self.surf
    }
}

impl std::ops::DerefMut for GpuState {
    fn deref_mut(&mut self) -> &mut WindowSurface {
        &mut self.surf
    }
}

struct App {
    scene: ViewerScene,
    options: ViewerOptions,
    state: Option<GpuState>,
    error: Option<WindowError>,
    camera: Camera,
    controls: Controls,
    route_t: f64,
    last_tick: Instant,
    started: Instant,
    title: FpsTitle,
    visible: Vec<BlockId>,
    /// Maps to draw this frame (indices into the far field's maps).
    far: Vec<usize>,
    /// The far field's selection (with the cull map that prunes its nodes in occlusion mode).
    far_step: Option<FarStep>,
    /// The walk's per-frame cull of the blocks.
    cull: CullStep,
    /// Maps drawn, summed over frames.
    far_total: u64,
    summary: ViewerSummary,
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: WindowError) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        event_loop.exit();
    }

    /// Window, instance with the window's display, surface, adapter able to present to it,
    /// device, renderer.
    fn init(&self, event_loop: &ActiveEventLoop) -> Result<GpuState, WindowError> {
        let surf = WindowSurface::open(
            event_loop,
            format!("blockwalk — {}", self.scene.scene.name),
            self.options.width,
            self.options.height,
        )?;
        let (width, height) = (surf.config.width, surf.config.height);
        let renderer = self.make_renderer(&surf.gpu, width, height)?;
        let far = self.make_far(&surf.gpu, width, height)?;
        Ok(GpuState {
            surf,
            renderer,
            far,
        })
    }

    fn make_renderer(
        &self,
        gpu: &Gpu,
        width: u32,
        height: u32,
    ) -> Result<MeshRenderer, RenderError> {
        let refs: Vec<(BlockId, &Mesh)> = self
            .scene
            .scene
            .draw_meshes()
            .iter()
            .map(|(b, m)| (*b, m))
            .collect();
        let r = MeshRenderer::with_ground(
            gpu,
            &refs,
            &self.scene.scene.ground,
            RenderOptions { width, height },
        )?;
        // The scene's terrain, when it has one: its cut is drawn on every frame (see `redraw`).
        match self.scene.scene.terrain_draw() {
            Some(t) => r.with_terrain(gpu, t),
            None => Ok(r),
        }
    }

    /// The far-field renderer at `width × height`, when the scene has a far field.
    fn make_far(
        &self,
        gpu: &Gpu,
        width: u32,
        height: u32,
    ) -> Result<Option<FarRenderer>, RenderError> {
        let Some(f) = &self.scene.far else {
            return Ok(None);
        };
        FarRenderer::new(gpu, f.field.as_ref(), (width, height)).map(Some)
    }

    fn resize(&mut self, size: PhysicalSize<u32>) -> Result<(), WindowError> {
        if size.width == 0 || size.height == 0 {
            return Ok(());
        }
        let Some(state) = self.state.as_ref() else {
            return Ok(());
        };
        if state.config.width == size.width && state.config.height == size.height {
            return Ok(());
        }
        let renderer = self.make_renderer(&state.gpu, size.width, size.height)?;
        let far = self.make_far(&state.gpu, size.width, size.height)?;
        let Some(state) = self.state.as_mut() else {
            return Ok(());
        };
        state.far = far;
        state.reconfigure(size.width, size.height);
        state.renderer = renderer;
        self.camera.aspect = size.width as f64 / size.height as f64;
        Ok(())
    }

    /// Moves the camera by the keys held (or along the route when playing).
    fn update_camera(&mut self, dt: f64) {
        let route = &self.scene.route;
        let on_route = route_time(
            route,
            &self.options,
            &self.controls,
            self.summary.frames,
            dt,
            &mut self.route_t,
        );
        if on_route {
            let aspect = self.camera.aspect;
            self.camera = route.camera_at(self.route_t);
            self.camera.aspect = aspect;
            return;
        }
        self.controls.fly(&mut self.camera, self.options.speed, dt);
    }

    /// One frame: cull, draw, present; in screenshot mode save the last frame and quit.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), WindowError> {
        let now = Instant::now();
        let dt = (now - self.last_tick).as_secs_f64().min(0.25);
        self.last_tick = now;
        self.update_camera(dt);
        let Some(height) = self.state.as_ref().map(|s| s.config.height) else {
            return Ok(());
        };
        self.visible.clear();
        self.far.clear();
        if let Some(step) = self.far_step.as_mut() {
            // The far field replaces the structure's culling: the selection prunes nodes and
            // the blocks left as meshes by the frustum and, with occlusion, the cull map.
            let culler = self
                .scene
                .scene
                .occlusion
                .as_ref()
                .filter(|_| self.scene.occlusion);
            let sel = step.select(culler, &self.camera, height, false).selection;
            self.visible = sel.meshes;
            self.far = sel.maps;
        } else {
            self.cull_structure()?;
        }
        let Some(state) = self.state.as_ref() else {
            return Ok(());
        };
        let far_pass = state.far.as_ref().filter(|_| !self.far.is_empty());
        // The terrain's cut for this camera (none without a terrain).
        let mut cut = Vec::new();
        if let Some(t) = self.scene.scene.terrain_draw() {
            t.cut(&self.camera, (state.config.width, height), &mut cut);
        }
        // With maps to draw, the far pass reads the composite back, not the mesh pass.
        let mut frame = state.renderer.draw_tiles(
            &state.gpu,
            &self.camera,
            &self.visible,
            &cut,
            super::Shading::Lit,
            far_pass.is_none(),
        )?;
        let mut far_pixels = 0;
        if let Some(far) = far_pass {
            let pass = far.draw(
                &state.gpu,
                &self.camera,
                &self.far,
                state.renderer.color_texture(),
                state.renderer.depth_texture(),
                FarReadback {
                    color: true,
                    depth: false,
                },
            )?;
            far_pixels = pass.far_pixels;
            if let Some(rgba) = pass.rgba {
                frame.rgba = rgba;
            }
        }
        self.present(event_loop, &frame, far_pixels)
    }

    /// Frustum (and occlusion) culling of the blocks through the viewer's structure, as the
    /// walk culls them.
    fn cull_structure(&mut self) -> Result<(), WindowError> {
        let scene = &self.scene.scene;
        let Some(index) = scene.index(self.scene.structure) else {
            return Err(WindowError::Scene(format!(
                "the scene has no {} structure",
                self.scene.structure
            )));
        };
        let mode = if self.scene.occlusion && scene.occlusion.is_some() {
            CullMode::FrustumOcclusion
        } else {
            CullMode::Frustum
        };
        self.cull.cull(scene, index, mode, &self.camera);
        self.visible.clear();
        self.visible.extend_from_slice(self.cull.draw_ids());
        Ok(())
    }

    /// Shows `frame` in the window, updates the title and the summary, and in screenshot mode
    /// saves the last frame and quits.
    fn present(
        &mut self,
        event_loop: &ActiveEventLoop,
        frame: &super::Frame,
        far_pixels: u64,
    ) -> Result<(), WindowError> {
        let Some(state) = self.state.as_ref() else {
            return Ok(());
        };
        if !state.show(&frame.rgba, frame.width, frame.height)? {
            return Ok(());
        }
        self.summary.frames += 1;
        self.summary.blocks = frame.timings.blocks;
        self.summary.triangles = frame.timings.triangles;
        self.summary.far_nodes = self.far.len();
        self.summary.far_pixels = far_pixels;
        self.far_total += self.far.len() as u64;
        if let Some(fps) = self.title.frame() {
            state.window.set_title(&format!(
                "blockwalk — {} — {:.1} fps — {} blocks, {} triangles{} — {}{}{}",
                self.scene.scene.name,
                fps,
                frame.timings.blocks,
                frame.timings.triangles,
                if self.far_step.is_some() {
                    format!(", {} far maps", self.far.len())
                } else {
                    String::new()
                },
                if self.far_step.is_some() {
                    "BlockMaps".to_string()
                } else {
                    self.scene.structure.to_string()
                },
                if self.scene.occlusion {
                    " + occlusion"
                } else {
                    ""
                },
                if self.controls.playing {
                    " — playing"
                } else {
                    ""
                },
            ));
        }
        if let Some(path) = &self.options.screenshot {
            if self.summary.frames >= self.options.frames.max(1) {
                frame
                    .save_png(path)
                    .map_err(|source| WindowError::Screenshot {
                        path: path.clone(),
                        source,
                    })?;
                self.summary.screenshot = Some(path.clone());
                event_loop.exit();
            }
        }
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.state.is_some() {
            return;
        }
        match self.init(event_loop) {
            Ok(state) => {
                state.opened(&mut self.camera, &mut self.summary);
                self.state = Some(state);
                self.started = Instant::now();
                self.last_tick = Instant::now();
            }
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Err(e) = self.resize(size) {
                    self.fail(event_loop, e);
                }
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            other => {
                if self.controls.input(&other, &mut self.camera) {
                    event_loop.exit();
                }
            }
        }
    }

    fn about_to_wait(&mut self, _event_loop: &ActiveEventLoop) {
        if let Some(state) = &self.state {
            state.window.request_redraw();
        }
    }
}
