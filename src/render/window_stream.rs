//! The viewer over a tiled city, streamed (feature `window`): every frame is a
//! [`Streamer`] frame (content fetched on worker threads, stand-ins where it has not arrived,
//! the render thread never waiting), drawn by the CPU hybrid renderer and copied into the
//! window's surface. The controls are the viewer's ([`super::window`]); while the route plays,
//! the content of the route ahead is prefetched. The title shows frames per second, maps and
//! meshes drawn, stand-ins, and the memory held.

use std::time::Instant;

use winit::application::ApplicationHandler;
use winit::event::WindowEvent;
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::window::WindowId;

use super::window::{
    route_time, Controls, FpsTitle, ViewerOptions, ViewerSummary, WindowError, WindowSurface,
};
use crate::geom::Camera;
use crate::route::CameraRoute;
use crate::stream::play::{StreamOptions, Streamer};
use crate::stream::StreamCity;

struct StreamApp<'a> {
    name: String,
    streamer: Streamer<'a>,
    route: CameraRoute,
    options: ViewerOptions,
    surf: Option<WindowSurface>,
    error: Option<WindowError>,
    camera: Camera,
    controls: Controls,
    route_t: f64,
    last_tick: Instant,
    started: Instant,
    title: FpsTitle,
    summary: ViewerSummary,
}

impl StreamApp<'_> {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: WindowError) {
        if self.error.is_none() {
            self.error = Some(e);
        }
        event_loop.exit();
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), WindowError> {
        let now = Instant::now();
        let dt = (now - self.last_tick).as_secs_f64().min(0.25);
        self.last_tick = now;
        let route = &self.route;
        let screenshot = self.options.screenshot.is_some();
        let on_route = route_time(
            route,
            &self.options,
            &self.controls,
            self.summary.frames,
            dt,
            &mut self.route_t,
        );
        let aspect = self.camera.aspect;
        // The route ahead, prefetched while it plays (one camera per 1/30 s).
        let mut ahead = Vec::new();
        if on_route {
            self.camera = route.camera_at(self.route_t);
            self.camera.aspect = aspect;
            let step = if screenshot {
                route.duration() / self.options.frames.max(2) as f64
            } else {
                1.0 / 30.0
            };
            for k in 1..=30 {
                let mut c = route.camera_at(self.route_t + k as f64 * step);
                c.aspect = aspect;
                ahead.push(c);
            }
        } else {
            self.controls.fly(&mut self.camera, self.options.speed, dt);
        }
        let Some(surf) = self.surf.as_ref() else {
            return Ok(());
        };
        let (w, h) = (surf.config.width, surf.config.height);
        self.streamer.set_size(w, h);
        let (img, _) = self.streamer.frame(&self.camera, &ahead, false);
        if !surf.show(img.as_raw(), w, h)? {
            return Ok(());
        }
        self.summary.frames += 1;
        let last = self.streamer.frames().last().cloned().unwrap_or_default();
        self.summary.far_nodes = last.maps;
        if let Some(fps) = self.title.frame() {
            surf.window.set_title(&format!(
                "blockwalk — {} (streamed) — {:.1} fps — {} maps, {} meshes, {} stand-ins — {:.0} MiB held{}",
                self.name,
                fps,
                last.maps,
                last.meshes,
                last.standin_maps + last.standin_boxes,
                last.resident_bytes as f64 / 1048576.0,
                if self.controls.playing { " — playing" } else { "" },
            ));
        }
        if let Some(path) = &self.options.screenshot {
            if self.summary.frames >= self.options.frames.max(1) {
                crate::output::write_png(path, &img).map_err(|e| WindowError::Screenshot {
                    path: path.clone(),
                    source: super::RenderError::Image {
                        file: path.clone(),
                        source: e,
                    },
                })?;
                self.summary.screenshot = Some(path.clone());
                event_loop.exit();
            }
        }
        Ok(())
    }
}

impl ApplicationHandler for StreamApp<'_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.surf.is_some() {
            return;
        }
        match WindowSurface::open(
            event_loop,
            format!("blockwalk — {} (streamed)", self.name),
            self.options.width,
            self.options.height,
        ) {
            Ok(surf) => {
                surf.opened(&mut self.camera, &mut self.summary);
                self.surf = Some(surf);
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
                if let (Some(s), true) = (self.surf.as_mut(), size.width > 0 && size.height > 0) {
                    s.reconfigure(size.width, size.height);
                    self.camera.aspect = size.width as f64 / size.height as f64;
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
        if let Some(s) = &self.surf {
            s.window.request_redraw();
        }
    }
}

/// Opens the window over the streamed `city` and runs until it is closed (or the screenshot
/// is written). `opts` sets the budget, the link, τ and the far field; its image size follows
/// the window's.
///
/// # Errors
/// As [`super::window::run_viewer`]; a far-field hierarchy the selector refuses.
pub fn run_stream_viewer(
    city: &StreamCity,
    opts: &StreamOptions,
    route: CameraRoute,
    options: ViewerOptions,
) -> Result<ViewerSummary, WindowError> {
    if options.width == 0 || options.height == 0 {
        return Err(WindowError::EmptyWindow {
            width: options.width,
            height: options.height,
        });
    }
    if !super::window::display_available() {
        return Err(WindowError::NoDisplay);
    }
    let streamer = Streamer::new(city, opts).map_err(|e| WindowError::Scene(e.to_string()))?;
    let event_loop = EventLoop::new().map_err(|source| WindowError::EventLoop { source })?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut camera = route.camera_at(route.start());
    camera.aspect = options.width as f64 / options.height as f64;
    let mut app = StreamApp {
        name: city.index.city.clone(),
        streamer,
        route_t: route.start(),
        route,
        controls: Controls::new(true),
        options,
        surf: None,
        error: None,
        camera,
        last_tick: Instant::now(),
        started: Instant::now(),
        title: FpsTitle::new(),
        summary: ViewerSummary::default(),
    };
    event_loop
        .run_app(&mut app)
        .map_err(|source| WindowError::EventLoop { source })?;
    if let Some(e) = app.error {
        return Err(e);
    }
    let secs = app.started.elapsed().as_secs_f64();
    app.summary.fps = if secs > 0.0 {
        app.summary.frames as f64 / secs
    } else {
        0.0
    };
    let frames = app.streamer.frames();
    if !frames.is_empty() {
        app.summary.far_nodes_mean =
            frames.iter().map(|f| f.maps as f64).sum::<f64>() / frames.len() as f64;
    }
    Ok(app.summary)
}
