//! The far field's part of a walk: whether the route needs it ([`Hybrid::new`]), each hybrid
//! frame (select, draw, measure against the mesh-only frame: [`Hybrid::frame`]), and the timing
//! probe that leaves it out where meshes draw faster ([`Hybrid::probe`]).

use super::far::{self, changed_pixels, FarDecision, FarRecord, FarSetup, SilhouetteBound};
use super::step::FarStep;
use super::{CullMode, WalkError};
use crate::geom::Camera;
use crate::scene::Scene;
use crate::visibility::FrameRenderer;

/// The far field over one walk.
pub(super) struct Hybrid<'a> {
    setup: FarSetup<'a>,
    decision: FarDecision,
    /// One selection per culling mode (each keeps its own previous frame); empty once the far
    /// field is left out.
    steps: Vec<(CullMode, FarStep)>,
    /// Who draws the hybrid frames.
    renderer: Option<&'a dyn FrameRenderer>,
    /// The exact geometry of the silhouette bound's second look, when given.
    bound: Option<Box<dyn SilhouetteBound + 'a>>,
    /// Image height the selection projects errors to.
    height: u32,
    records: Vec<FarRecord>,
    /// Seconds spent on the referenced frames' image measures with the bound's second look.
    bound_s: f64,
}

/// What one hybrid frame needs of the walk's mesh-only frame.
pub(super) struct MeshFrame<'a> {
    pub frame: usize,
    pub mode: CullMode,
    pub camera: &'a Camera,
    /// The mesh-only frame's picture, when the walk compares against it.
    pub image: Option<&'a image::RgbaImage>,
    /// Its culling + drawing seconds.
    pub seconds: f64,
    /// Triangles per block id.
    pub triangles: &'a dyn Fn(crate::blocks::BlockId) -> u64,
}

impl<'a> Hybrid<'a> {
    /// The far field of a walk of `scene` along `cameras` in `modes`, drawn by `renderer` at an
    /// image `height` tall: decides whether the route needs it (some node qualifies on some
    /// frame) and prepares a selection per mode.
    pub(super) fn new(
        scene: &'a Scene,
        setup: FarSetup<'a>,
        modes: &[CullMode],
        cameras: &[Camera],
        renderer: Option<&'a dyn FrameRenderer>,
        height: u32,
        notes: &mut Vec<String>,
    ) -> Result<Self, WalkError> {
        let field = setup.field;
        let base = FarStep::new(
            field
                .selector(&scene.bounds, setup.select)
                .map_err(|source| WalkError::Far {
                    city: scene.name.clone(),
                    source,
                })?,
            scene.occlusion.as_ref(),
        );
        let qualifies = field.is_empty() || {
            let mut probe = base.clone();
            cameras.iter().any(|c| {
                probe.reset();
                !probe
                    .select(None, c, height, false)
                    .selection
                    .maps
                    .is_empty()
            })
        };
        let reason = if field.is_empty() {
            Some(format!(
                "the city has no {} (meshes are cheaper for every node)",
                field.name()
            ))
        } else if setup.leave_out && !qualifies {
            Some(format!(
                "no node of the {} qualifies on any frame of the route at τ = {} px: the walk runs without the far field",
                field.name(),
                setup.select.tau_px
            ))
        } else {
            None
        };
        if let Some(r) = &reason {
            notes.push(format!("far field left out: {r}"));
        }
        let decision = FarDecision {
            representation: field.name().to_string(),
            used: reason.is_none(),
            reason,
            left_out_after: None,
        };
        let steps = if decision.used {
            modes.iter().map(|&m| (m, base.clone())).collect()
        } else {
            Vec::new()
        };
        if setup.reference && setup.source.is_none() {
            notes.push(
                "silhouette bound not checked: no building geometry was given to the far field \
                 (silhouette_ratio_max and the bound's counts are null; silhouette_px_max is the \
                 raw image distance)"
                    .into(),
            );
        }
        Ok(Self {
            bound: setup.source.map(|s| field.silhouette_bound(s)),
            setup,
            decision,
            steps,
            renderer,
            height,
            records: Vec::new(),
            bound_s: 0.0,
        })
    }

    /// Whether the far field is still drawn.
    pub(super) fn active(&self) -> bool {
        !self.steps.is_empty()
    }

    /// Whether hybrid frames are compared with the mesh-only frames.
    pub(super) fn reference(&self) -> bool {
        self.setup.reference
    }

    /// Selects, draws and (with the mesh frame's image) measures one hybrid frame.
    pub(super) fn frame(&mut self, scene: &Scene, mesh: MeshFrame<'_>, notes: &mut Vec<String>) {
        let Some(slot) = self.steps.iter().position(|(m, _)| *m == mesh.mode) else {
            return;
        };
        let f = mesh.frame;
        let culler = (mesh.mode == CullMode::FrustumOcclusion)
            .then_some(scene.occlusion.as_ref())
            .flatten();
        let pick =
            self.steps[slot]
                .1
                .select(culler, mesh.camera, self.height, mesh.image.is_some());
        let sel = pick.selection;
        let mut rec = FarRecord {
            frame: f,
            mode: mesh.mode,
            select_s: pick.seconds,
            render_s: None,
            frame_s: pick.seconds,
            mesh_frame_s: mesh.seconds,
            passes: Vec::new(),
            mesh_blocks: sel.meshes.len(),
            mesh_triangles: sel.meshes.iter().map(|&b| (mesh.triangles)(b)).sum(),
            far_nodes: sel.maps.len(),
            far_blocks: sel.stats.map_blocks,
            far_pixels: None,
            stats: sel.stats,
            image: None,
            gpu_time: false,
        };
        if let Some(r) = self.renderer {
            self.draw(r, &mesh, &sel, pick.frozen.as_ref(), &mut rec, notes);
        }
        self.records.push(rec);
    }

    /// Draws the hybrid frame of `sel` into `rec` and, with the mesh frame's image, measures it
    /// (coverage, PSNR, silhouette bound, popping against the `frozen` selection).
    fn draw(
        &mut self,
        r: &dyn FrameRenderer,
        mesh: &MeshFrame<'_>,
        sel: &crate::blockmap::Selection,
        frozen: Option<&crate::blockmap::Selection>,
        rec: &mut FarRecord,
        notes: &mut Vec<String>,
    ) {
        let f = mesh.frame;
        let drawn = match r.draw_with_far(mesh.camera, &sel.meshes, &sel.maps, mesh.image.is_some())
        {
            Ok(d) => d,
            Err(e) => {
                notes.push(format!("frame {f}: drawing the hybrid frame failed: {e}"));
                return;
            }
        };
        rec.render_s = Some(drawn.seconds);
        rec.gpu_time = drawn.gpu_time;
        rec.frame_s = rec.select_s + drawn.seconds;
        rec.passes = drawn
            .passes
            .iter()
            .map(|(n, s)| (n.to_string(), *s))
            .collect();
        rec.far_pixels = drawn.far_pixels;
        let (Some(mesh_img), Some(hyb)) = (mesh.image, drawn.image.as_ref()) else {
            return;
        };
        let Some(bg) = r.draw(mesh.camera, &[], true).ok().and_then(|d| d.image) else {
            notes.push(format!(
                "frame {f}: the background frame could not be drawn"
            ));
            return;
        };
        let fb = self
            .bound
            .as_ref()
            .map(|g| g.frame(sel, mesh.camera, self.setup.select.tau_px));
        let t_err = std::time::Instant::now();
        let mut err = far::image_error_with_bound(mesh_img, hyb, &bg, fb.as_deref());
        if fb.is_some() {
            self.bound_s += t_err.elapsed().as_secs_f64();
        }
        if let Some(fr) = frozen.filter(|fr| !far::same_selection(fr, sel)) {
            match r.draw_with_far(mesh.camera, &fr.meshes, &fr.maps, true) {
                Ok(d) => {
                    if let Some(img) = d.image {
                        err.popping_colour_px = changed_pixels(&img, hyb);
                        err.popping_px = far::coverage_changed(&img, hyb, &bg);
                    }
                }
                Err(e) => notes.push(format!("frame {f}: drawing the popping frame failed: {e}")),
            }
        }
        rec.image = Some(err);
    }

    /// The timing probe, after frame `f` of `frames`: after the first
    /// [`FarSetup::probe_frames`] frames, leaves the far field out when hybrid frames
    /// (GPU-timed) are no faster than mesh-only ones.
    pub(super) fn probe(&mut self, f: usize, frames: usize, notes: &mut Vec<String>) {
        let x = &self.setup;
        if !(self.decision.used
            && x.leave_out
            && f + 1 == x.probe_frames.max(1)
            && f + 1 < frames
            && !self.records.is_empty()
            && self.records.iter().all(|r| r.gpu_time))
        {
            return;
        }
        let n = self.records.len() as f64;
        let hyb = self.records.iter().map(|r| r.frame_s).sum::<f64>() / n;
        let mesh = self.records.iter().map(|r| r.mesh_frame_s).sum::<f64>() / n;
        if hyb < mesh {
            return;
        }
        let reason = format!(
            "meshes draw faster than {} here: {:.3} ms hybrid vs {:.3} ms mesh-only per frame over the first {} frames",
            self.setup.field.name(),
            hyb * 1e3,
            mesh * 1e3,
            f + 1
        );
        notes.push(format!("far field left out after frame {f}: {reason}"));
        self.decision.used = false;
        self.decision.left_out_after = Some(f);
        self.decision.reason = Some(reason);
        self.steps.clear();
    }

    /// The hybrid frames, the decision and the selection settings, with a note on the bound's
    /// cost.
    pub(super) fn finish(
        self,
        notes: &mut Vec<String>,
    ) -> (Vec<FarRecord>, FarDecision, crate::blockmap::SelectOptions) {
        if self.bound.is_some() {
            let checked = self
                .records
                .iter()
                .filter(|r| r.image.is_some_and(|i| i.silhouette_ratio_max.is_some()))
                .count();
            if checked > 0 {
                notes.push(format!(
                    "silhouette bound checked with the exact geometry on {checked} hybrid frames \
                     ({:.3} s for their image measures in all)",
                    self.bound_s
                ));
            }
        }
        (self.records, self.decision, self.setup.select)
    }
}
