//! The render surface on the device (`shaders/embed_surface.wgsl`): on random deformed states
//! in every layout, before and after a cut-like patch, the vertex buffer equals its CPU twin
//! (bit for bit where the device rounds like the CPU) and the float64 evaluation from the
//! positions a full readback gives, to float32 rounding.

use crate::{common, cut_box, models};
use lancet::engine::gpu::GpuEngine;
use lancet::engine::{Engine, SimConfig};
use lancet::layout::LayoutKind;
use lancet::mesh::generate::BoxGrid;
use lancet::model::PackedModel;
use lancet::surface::{Embedding, RenderSurface};
use lancet::twin::embed_surface::embed_surface_cpu;
use models::{random_box, random_diff, random_state, Rng};
use rstest::rstest;

/// Random vertices in and up to 3 mm around the 5 x 4 x 3 cm box of [`random_box`].
fn surface_around_box(rng: &mut Rng) -> (Embedding, RenderSurface) {
    let mesh = BoxGrid::cube_cells([5, 4, 3], 0.01).build().unwrap();
    let positions: Vec<[f64; 3]> = (0..700)
        .map(|_| [0.05, 0.04, 0.03].map(|hi: f64| -3e-3 + (hi + 6e-3) * rng.next()))
        .collect();
    let triangles = (0..700u32 / 3)
        .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
        .collect();
    let surface = RenderSurface::new(positions, triangles, "around the box").unwrap();
    let e = Embedding::new(&mesh, &surface).unwrap();
    assert!(e.outside_count() > 50 && e.outside_count() < 650);
    (e, surface)
}

/// The device's vertices against the twin and the float64 evaluation; returns how many
/// vertices moved off their rest position (the state must be non-trivial).
fn check(engine: &mut GpuEngine, e: &Embedding) -> usize {
    engine.set_render_surface(e).unwrap();
    let got = engine.read_render_surface().unwrap();
    let bound = engine.bound_vertices(e).unwrap();
    let want = embed_surface_cpu(&bound, &engine.raw_state().unwrap().0);
    assert_eq!(got.len(), e.len());
    let exact = common::rounds_like_cpu();
    for (v, (g, w)) in got.iter().zip(&want).enumerate() {
        if exact {
            assert_eq!(g.map(f32::to_bits), w.map(f32::to_bits), "vertex {v}");
        } else {
            for c in 0..3 {
                assert!(
                    (g[c] - w[c]).abs() <= 1e-6 * w[c].abs().max(1e-2),
                    "vertex {v}"
                );
            }
        }
    }
    let x = engine.positions();
    let f64_want = e.evaluate(&x);
    let mut moved = 0;
    for (v, (g, w)) in got.iter().zip(&f64_want).enumerate() {
        for c in 0..3 {
            // Float32 rest positions and displacements of centimetre coordinates.
            assert!(
                (g[c] as f64 - w[c]).abs() < 2e-8,
                "vertex {v}: device {g:?}, float64 {w:?}"
            );
        }
        moved += (0..3).any(|c| (w[c] - e.rest[v][c]).abs() > 1e-5) as usize;
    }
    moved
}

#[rstest]
fn device_surface_equals_its_twin(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    let Some(ctx) = common::gpu() else { return };
    let model = random_box(7, false);
    let mut engine = GpuEngine::with_context(ctx, &model, SimConfig::new(2e-5), kind).unwrap();
    let (x, v) = random_state(&model, 7);
    engine.set_state(&x, &v);
    engine.step(3);
    let (e, _) = surface_around_box(&mut Rng(5));
    let moved = check(&mut engine, &e);
    assert!(moved > 300, "only {moved} vertices moved");
    // A cut-like patch moves node slots; the surface, bound again, follows.
    let diff = random_diff(&model, 300);
    let mut next: PackedModel = model.clone();
    next.apply(&diff).unwrap();
    engine.patch(&next, &diff).unwrap();
    engine.step(2);
    assert!(check(&mut engine, &e) > 300);
}

/// After each sweep of a cut right through a box, the surface rebound on the CPU goes to the
/// device with only the bound vertices that changed (rebound, or bound to nodes the patch moved
/// in the layout); with the two pieces pulled apart on the device, the vertex buffer equals its
/// twin and every vertex moved as the piece of its own tet.
#[rstest]
fn device_surface_follows_its_side_after_a_rebind(
    #[values(LayoutKind::Connectivity, LayoutKind::Valence, LayoutKind::Edges)] kind: LayoutKind,
) {
    use lancet::cut::CutMethod;
    use lancet::surface::Rebinder;

    let Some(ctx) = common::gpu() else { return };
    let mut cutter = cut_box::cutter(CutMethod::Separate);
    let mut packed = cutter.model().pack(cutter.mesh()).unwrap();
    let mut engine = GpuEngine::with_context(ctx, &packed, SimConfig::new(1e-5), kind).unwrap();
    let surface = cut_box::cloud(29, 900);
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = Rebinder::new(cutter.mesh(), &e);
    assert_eq!(engine.set_render_surface(&e).unwrap(), 48 * 900);
    let mut rebound = 0;
    for sweep in cut_box::sweeps(3) {
        let before = engine.bound_vertices(&e).unwrap();
        let (outcome, n) = cut_box::cut_once(&mut cutter, &sweep, Some((&mut rebinder, &mut e)));
        rebound += n;
        packed.apply(&outcome.diff).unwrap();
        engine.patch(&packed, &outcome.diff).unwrap();
        let after = engine.bound_vertices(&e).unwrap();
        let differ = before.iter().zip(&after).filter(|(a, b)| a != b).count();
        assert!(differ >= n.min(1), "{kind:?}: the rebound vertices changed");
        assert_eq!(
            engine.set_render_surface(&e).unwrap(),
            48 * differ as u64,
            "{kind:?}: only the changed vertices go up"
        );
    }
    let pulled = cut_box::Pulled::apart(cutter.mesh());
    engine.set_state(&pulled.x, &vec![[0.0; 3]; pulled.x.len()]);
    let got = engine.read_render_surface().unwrap();
    let bound = engine.bound_vertices(&e).unwrap();
    let want = embed_surface_cpu(&bound, &engine.raw_state().unwrap().0);
    let exact = common::rounds_like_cpu();
    for (v, (g, w)) in got.iter().zip(&want).enumerate() {
        if exact {
            assert_eq!(g.map(f32::to_bits), w.map(f32::to_bits), "vertex {v}");
        }
        let moved = nalgebra::Vector3::from([0, 1, 2].map(|c| g[c] as f64 - e.rest[v][c]));
        let side = pulled.of_tet(e.bindings[v].tet());
        // Float32 rest positions and displacements of centimetre coordinates.
        assert!(
            (moved - side).norm() < 1e-8,
            "{kind:?}: vertex {v} moved {moved:?}, its piece {side:?}"
        );
    }
    assert!(rebound > 40, "{kind:?}: {rebound} rebound");
}

/// A closed surface cut right through, split and capped after each sweep: the embedding grows
/// by the crossings' vertices, and only those and the vertices whose binding changed go up
/// (within the buffers' room); with the pieces pulled apart on the device, the grown vertex
/// buffer equals its twin and the float64 evaluation, every drawn triangle moving with one
/// piece.
#[test]
fn device_surface_grows_with_the_caps() {
    use lancet::cut::CutMethod;
    use lancet::surface::{Capper, Rebinder};

    let Some(ctx) = common::gpu() else { return };
    let mut cutter = cut_box::cutter(CutMethod::Subdivide);
    let mut packed = cutter.model().pack(cutter.mesh()).unwrap();
    let kind = LayoutKind::Edges;
    let mut engine = GpuEngine::with_context(ctx, &packed, SimConfig::new(1e-5), kind).unwrap();
    let surface = cut_box::closed_box([0.001; 3], [0.049, 0.039, 0.029], [10, 8, 6]);
    let own = surface.vertex_count();
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = Rebinder::new(cutter.mesh(), &e);
    let mut capper = Capper::new(own, &surface.triangles);
    engine.set_render_surface(&e).unwrap();
    let mut triangles = Vec::new();
    for sweep in cut_box::sweeps(3) {
        let before = engine.bound_vertices(&e).unwrap();
        let (outcome, _) = cut_box::cut_once(&mut cutter, &sweep, Some((&mut rebinder, &mut e)));
        triangles = capper.cut(&mut e, cutter.mesh(), &sweep).triangles;
        packed.apply(&outcome.diff).unwrap();
        engine.patch(&packed, &outcome.diff).unwrap();
        let after = engine.bound_vertices(&e).unwrap();
        let changed = after
            .iter()
            .enumerate()
            .filter(|(v, b)| before.get(*v) != Some(b))
            .count();
        assert!(after.len() > own, "the cut added vertices");
        assert_eq!(
            engine.set_render_surface(&e).unwrap(),
            48 * changed as u64,
            "only the changed and added vertices go up"
        );
    }
    assert!(cut_box::not_closed(&triangles).is_none());
    let pulled = cut_box::Pulled::apart(cutter.mesh());
    engine.set_state(&pulled.x, &vec![[0.0; 3]; pulled.x.len()]);
    let got = engine.read_render_surface().unwrap();
    assert_eq!(got.len(), e.len());
    let bound = engine.bound_vertices(&e).unwrap();
    let want = embed_surface_cpu(&bound, &engine.raw_state().unwrap().0);
    let f64_want = e.evaluate(&pulled.x);
    let exact = common::rounds_like_cpu();
    for (v, (g, w)) in got.iter().zip(&want).enumerate() {
        if exact {
            assert_eq!(g.map(f32::to_bits), w.map(f32::to_bits), "vertex {v}");
        }
        for c in 0..3 {
            assert!((g[c] as f64 - f64_want[v][c]).abs() < 2e-8, "vertex {v}");
        }
    }
    let moved = |v: u32| {
        nalgebra::Vector3::from(
            [0, 1, 2].map(|c| got[v as usize][c] as f64 - e.rest[v as usize][c]),
        )
    };
    // Each vertex is within 2e-8 of the float64 evaluation (checked above), so two vertices of
    // one piece moved alike to 4e-8 on any device (a fused multiply-add rounds differently
    // from lavapipe); the two pieces moved about 1.1e-2 apart.
    for t in &triangles {
        for k in 1..3 {
            let d = (moved(t[0]) - moved(t[k])).norm();
            assert!(
                d < 4e-8,
                "triangle {t:?} stretched across the opening ({d:e} m)"
            );
        }
    }
}

/// The render surface's index buffer on the device, through the simulation a host steps: after
/// each cut it holds exactly the capped triangles the host made (read back and compared), it
/// grows with them, and neither a step without a cut nor the same triangles given again writes
/// a byte of it.
#[test]
fn device_render_indices_follow_the_caps() {
    use lancet::cut::CutMethod;
    use lancet::engine::gpu::buffers::read_bytes;
    use lancet::surface::{Capper, Rebinder};
    use lancet::Simulation;

    let Some(ctx) = common::gpu() else { return };
    let mut cutter = cut_box::cutter(CutMethod::Separate);
    let packed = cutter.model().pack(cutter.mesh()).unwrap();
    let mut sim = Simulation::with_gpu_context(
        packed,
        ctx.clone(),
        SimConfig::new(1e-5),
        LayoutKind::Edges.into(),
    )
    .unwrap();
    let surface = cut_box::closed_box([0.001; 3], [0.049, 0.039, 0.029], [10, 8, 6]);
    let mut e = Embedding::new(cutter.mesh(), &surface).unwrap();
    let mut rebinder = Rebinder::new(cutter.mesh(), &e);
    let mut capper = Capper::new(e.len(), &surface.triangles);
    assert!(sim.gpu_render_indices().unwrap().is_none(), "none set yet");
    sim.set_render_surface(&e).unwrap();
    // A triangle naming a vertex the surface does not have is refused, with the vertex named.
    let bad = sim
        .set_render_triangles(&[[0, 1, e.len() as u32]])
        .unwrap_err()
        .to_string();
    assert!(bad.contains(&format!("vertex {}", e.len())), "{bad}");

    // What the device's index buffer holds, and the bytes written to it so far.
    let held = |sim: &mut Simulation| {
        let i = sim.gpu_render_indices().unwrap().expect("set");
        let bytes = read_bytes(&ctx, i.buffer, u64::from(i.count) * 4).unwrap();
        let t: Vec<[u32; 3]> = bytemuck::cast_slice::<u8, u32>(&bytes)
            .chunks(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        (t, i.uploaded)
    };
    sim.set_render_triangles(&surface.triangles).unwrap();
    let (t, mut uploaded) = held(&mut sim);
    assert_eq!(t, surface.triangles);
    assert_eq!(uploaded, 12 * surface.triangles.len() as u64);
    let mut grew = false;
    for sweep in cut_box::sweeps(3) {
        let (outcome, _) = cut_box::cut_once(&mut cutter, &sweep, Some((&mut rebinder, &mut e)));
        let capped = capper.cut(&mut e, cutter.mesh(), &sweep);
        sim.apply_with(&outcome.diff, true).unwrap();
        sim.set_render_surface(&e).unwrap();
        sim.set_render_triangles(&capped.triangles).unwrap();
        let (t, now) = held(&mut sim);
        assert_eq!(t, capped.triangles, "the device holds the capped surface");
        assert!(
            now > uploaded && now - uploaded <= 12 * capped.triangles.len() as u64,
            "{} bytes written for {} triangles",
            now - uploaded,
            capped.triangles.len()
        );
        grew |= capped.triangles.len() > surface.triangles.len();
        uploaded = now;
        // No cut: a step, the same triangles again, another frame: nothing written.
        sim.run(1).unwrap();
        sim.set_render_triangles(&capped.triangles).unwrap();
        let (t, now) = held(&mut sim);
        assert_eq!(t, capped.triangles);
        assert_eq!(now, uploaded, "written again without a cut");
        let v = sim.gpu_render_vertices().unwrap().expect("set");
        assert_eq!(v.count as usize, e.len());
    }
    assert!(grew, "the caps added triangles");
}
