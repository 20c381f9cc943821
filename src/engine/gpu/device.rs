//! What the GPU engine does because its state lives on a device: [`DeviceEngine`] for
//! [`GpuEngine`] (waiting, device timings, the surface it culls against, the divergence probe).

use super::*;

impl DeviceEngine for GpuEngine {
    fn last_device_seconds(&self) -> Option<f64> {
        // A failed readback only loses the timing; the step itself is unaffected.
        self.timer.as_ref()?.last_seconds(&self.ctx).ok().flatten()
    }

    fn wait(&mut self) {
        // This engine's last step only: the device is shared (`GpuContext::new`), and waiting
        // for all of it would wait for other engines' work too.
        let _ = self.ctx.device.poll(wgpu::PollType::Wait {
            submission_index: self.last_submission.clone(),
            timeout: None,
        });
    }

    fn set_surface(&mut self, triangles: &[[u32; 3]]) -> Result<()> {
        GpuEngine::set_surface(self, triangles)
    }

    fn edit_surface(&mut self, triangles: &[[u32; 3]], changed: &[u32]) -> Result<()> {
        GpuEngine::edit_surface(self, triangles, changed)
    }

    fn cull_tools(&mut self, boxes: &[ToolBox]) -> Result<Vec<[u32; 2]>> {
        GpuEngine::cull_tools(self, boxes).map(|r| r.candidates)
    }

    #[cfg(feature = "collide")]
    fn cull_self(&mut self, margin: f64) -> Result<Vec<[u32; 2]>> {
        GpuEngine::cull_self(self, margin).map(|r| r.pairs)
    }

    fn health(&self) -> Result<Health> {
        let h = self
            .health
            .run(&self.ctx, self.phase, self.dispatch.nodes)?;
        let (kinetic, gravity) = h.totals();
        let order = &self.layout.order().order;
        Ok(Health {
            non_finite: h
                .first_bad
                .map(|i| order[i as usize])
                .filter(|&m| m != NodeOrder::HOLE)
                .map(|m| m as usize),
            kinetic,
            gravity,
        })
    }
}
