//! A fixture stepped by an embedding program through the world's API (tools added and posed
//! by hand from the scene's trajectories) gives what `run_scene` gives for it, to the bit: the
//! scene runner and an embedder run the same step.

use std::path::{Path, PathBuf};

use lancet::scene::expect::max_displacement;
use lancet::scene::{run_scene, RunOptions, Scene};
use lancet::world::WorldBuilder;
use rstest::rstest;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fixtures/scenes")
        .join(name)
}

#[rstest]
#[case::probe_press("probe_press.ron", 2000)]
#[case::cut_box_through("cut_box_through.ron", 250)]
fn a_fixture_stepped_through_the_world_api_gives_what_run_scene_gives(
    #[case] name: &str,
    #[case] steps: u64,
) {
    let path = fixture(name);
    let scene = Scene::read(&path).unwrap();
    let opts = RunOptions {
        steps: Some(steps),
        no_output: true,
        ..RunOptions::default()
    };
    let summary = run_scene(&scene, &path, &opts, |_, _| {}).unwrap();

    // The embedder's way: build, add the tools, enable cutting, pose by hand every step.
    let mut world = WorldBuilder::from_scene(&scene, &path, &opts)
        .unwrap()
        .build()
        .unwrap();
    if let Some(cut) = &scene.cut {
        let fraction = match scene.dt {
            lancet::scene::TimeStep::BoundFraction(f) => f,
            lancet::scene::TimeStep::Seconds(_) => 0.9,
        };
        world
            .enable_cutting(cut.settings(None, scene.checks_cuts(), fraction))
            .unwrap();
    }
    let handles: Vec<_> = scene
        .tools
        .iter()
        .map(|t| {
            world
                .add_tool(&t.name, t.shape, t.trajectory.pose_at(0.0))
                .unwrap()
        })
        .collect();
    let mut max_force = vec![0.0f64; handles.len()];
    let mut final_force = vec![[0.0; 3]; handles.len()];
    let mut cuts = 0;
    for _ in 0..steps {
        let t = world.sim().time() + world.sim().config().dt;
        for (h, tool) in handles.iter().zip(&scene.tools) {
            world.set_tool_pose(*h, tool.trajectory.pose_at(t)).unwrap();
        }
        let report = world.step().unwrap();
        for (k, r) in report.tools.iter().enumerate() {
            if !r.cuts {
                max_force[k] = max_force[k].max(r.force.norm());
                final_force[k] = r.force.into();
            }
        }
        cuts += report.cuts.len();
        // What run_scene does between chunks; it only matters when an inversion check falls
        // on a cut tet, which none of these fixtures has.
        world.rewatch().unwrap();
    }

    assert_eq!(summary.steps, steps);
    for (k, tool) in summary.tools.iter().enumerate() {
        assert_eq!(tool.max_force, max_force[k], "{name}: {}", tool.name);
        assert_eq!(tool.final_force, final_force[k], "{name}: {}", tool.name);
    }
    if scene
        .tools
        .iter()
        .any(|t| !matches!(t.shape, lancet::collide::ToolShape::Blade { .. }))
    {
        assert!(
            max_force.iter().any(|&f| f > 0.0),
            "{name}: no tool touched"
        );
    }
    let x = world.positions();
    assert_eq!(
        summary.max_displacement,
        max_displacement(world.model(), &x),
        "{name}"
    );
    assert_eq!(
        summary.energy.total(),
        world.sim().energy().total(),
        "{name}"
    );
    match (&summary.cuts, world.cut_report()) {
        (Some(a), Some(b)) => {
            assert!(cuts > 0, "{name}: nothing was cut");
            assert_eq!(a.cuts, cuts, "{name}");
            assert_eq!(a.events.len(), b.events.len(), "{name}");
            assert_eq!(
                (a.nodes_added, a.tets_removed, a.fragments),
                (b.nodes_added, b.tets_removed, b.fragments),
                "{name}"
            );
            assert_eq!(a.max_opening, b.max_opening, "{name}");
        }
        (None, None) => {}
        (a, b) => panic!("{name}: cut reports differ: {a:?} / {b:?}"),
    }
}
