//! Tool trajectories interpolate and clamp as documented, swept bounds hold every point of the
//! shape over the motion, and scenes parse tools with clear errors.

use std::f64::consts::FRAC_PI_2;

use lancet::collide::{Keyframe, Tool, ToolShape, Trajectory};
use nalgebra::{Isometry3, Point3, UnitQuaternion, Vector3};

fn key(time: f64, translation: [f64; 3], rotation: [f64; 3]) -> Keyframe {
    Keyframe {
        time,
        translation,
        rotation,
    }
}

#[test]
fn slerp_midpoint_of_a_quarter_turn_is_an_eighth_turn() {
    let traj = Trajectory::Keyframes(vec![
        key(0.0, [0.0; 3], [0.0; 3]),
        key(2.0, [0.2, 0.0, -0.1], [0.0, 0.0, FRAC_PI_2]),
    ]);
    let mid = traj.pose_at(1.0);
    let expected = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), FRAC_PI_2 / 2.0);
    assert!(mid.rotation.angle_to(&expected) < 1e-12);
    assert!((mid.translation.vector - Vector3::new(0.1, 0.0, -0.05)).norm() < 1e-15);
    // A quarter of the way: 22.5 degrees about z.
    let q = traj.pose_at(0.5).rotation;
    assert!((q.angle() - FRAC_PI_2 / 4.0).abs() < 1e-12);
    assert!((q.axis().unwrap().into_inner() - Vector3::z()).norm() < 1e-12);
}

#[test]
fn keyframes_clamp_before_the_first_and_after_the_last() {
    let traj = Trajectory::Keyframes(vec![
        key(0.5, [0.1, 0.0, 0.0], [0.0, 0.3, 0.0]),
        key(1.0, [0.2, 0.0, 0.0], [0.0, 0.0, 0.0]),
        key(3.0, [0.2, 0.4, 0.0], [0.0, 0.0, 1.0]),
    ]);
    let first = traj.pose_at(0.5);
    for t in [-10.0, 0.0, 0.5, f64::NAN] {
        assert_eq!(traj.pose_at(t), first, "t = {t}");
    }
    let last = traj.pose_at(3.0);
    assert_eq!(traj.pose_at(100.0), last);
    assert!((last.translation.vector - Vector3::new(0.2, 0.4, 0.0)).norm() < 1e-15);
    // Exactly on an inner keyframe.
    let k1 = traj.pose_at(1.0);
    assert!((k1.translation.vector - Vector3::new(0.2, 0.0, 0.0)).norm() < 1e-15);
    assert!(k1.rotation.angle() < 1e-12);
    // Between the second and third: halfway along y.
    assert!((traj.pose_at(2.0).translation.y - 0.2).abs() < 1e-15);
    // One keyframe: the tool holds still.
    let still = Trajectory::Keyframes(vec![key(0.0, [1.0, 2.0, 3.0], [0.0; 3])]);
    assert_eq!(
        still.pose_at(5.0).translation.vector,
        Vector3::new(1.0, 2.0, 3.0)
    );
}

#[test]
fn velocity_trajectory_moves_and_turns_at_constant_rate() {
    let traj = Trajectory::Velocity {
        translation: [0.3, -0.2, 0.5],
        rotation: [FRAC_PI_2, 0.0, 0.0],
        linear: [0.0, 0.0, -0.01],
        angular: [0.0, 0.0, 0.5],
    };
    let p = traj.pose_at(2.0);
    assert!((p.translation.vector - Vector3::new(0.3, -0.2, 0.48)).norm() < 1e-15);
    let start = UnitQuaternion::from_scaled_axis(Vector3::new(FRAC_PI_2, 0.0, 0.0));
    let turn = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 1.0);
    assert!(p.rotation.angle_to(&(turn * start)) < 1e-12);
    // Before time 0 the tool is at the start.
    assert_eq!(traj.pose_at(-1.0), traj.pose_at(0.0));
}

#[test]
fn trajectory_errors_name_the_keyframe() {
    let e = Trajectory::Keyframes(vec![])
        .validate()
        .unwrap_err()
        .to_string();
    assert!(e.contains("no keyframes"), "{e}");
    let e = Trajectory::Keyframes(vec![
        key(0.0, [0.0; 3], [0.0; 3]),
        key(0.0, [0.0; 3], [0.0; 3]),
    ])
    .validate()
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("keyframe 1") && e.contains("increasing time"),
        "{e}"
    );
}

/// Small deterministic generator for random poses.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    fn vec(&mut self, scale: f64) -> Vector3<f64> {
        Vector3::new(
            self.range(-scale, scale),
            self.range(-scale, scale),
            self.range(-scale, scale),
        )
    }
    fn rotation(&mut self, max_angle: f64) -> [f64; 3] {
        let axis = self.vec(1.0).try_normalize(1e-6).unwrap_or_else(Vector3::x);
        (axis * self.range(0.0, max_angle)).into()
    }
}

fn shapes() -> Vec<ToolShape> {
    vec![
        ToolShape::Probe {
            radius: 0.002,
            length: 0.06,
        },
        ToolShape::Probe {
            radius: 0.0003,
            length: 0.01,
        },
        ToolShape::Sphere { radius: 0.003 },
        ToolShape::Blade {
            width: 0.008,
            length: 0.03,
            thickness: 0.0004,
        },
        ToolShape::Grasper {
            jaw: [0.001, 0.002, 0.008],
            opening: 0.006,
        },
    ]
}

/// Sample the shape's surface (support points in many directions, which include every vertex
/// and the extreme points of every round part) at many times of the motion between two
/// keyframes, and check that all lie in the swept bounds.
fn check_swept(rng: &mut Rng, max_angle: f64, max_move: f64) -> f64 {
    let mut worst_slack = f64::INFINITY;
    for shape in shapes() {
        for _ in 0..40 {
            let origin = [0.3, -0.2, 0.5];
            let t0: [f64; 3] = (Vector3::from(origin) + rng.vec(0.01)).into();
            let t1: [f64; 3] = (Vector3::from(t0) + rng.vec(max_move)).into();
            let traj = Trajectory::Keyframes(vec![
                key(0.0, t0, rng.rotation(std::f64::consts::PI)),
                key(1.0, t1, [0.0; 3]),
            ]);
            // The second rotation is the first turned by up to `max_angle`.
            let Trajectory::Keyframes(mut frames) = traj else {
                unreachable!()
            };
            let q0 = UnitQuaternion::from_scaled_axis(Vector3::from(frames[0].rotation));
            let q1 = UnitQuaternion::from_scaled_axis(Vector3::from(rng.rotation(max_angle))) * q0;
            frames[1].rotation = q1.scaled_axis().into();
            let traj = Trajectory::Keyframes(frames);
            let (pose0, pose1) = (traj.pose_at(0.0), traj.pose_at(1.0));
            let tool = Tool::new(shape, pose0).expect("valid shape");
            let bounds = tool.swept_aabb(&pose0, &pose1, 0.0);
            for i in 0..=64 {
                let pose: Isometry3<f64> = traj.pose_at(f64::from(i) / 64.0);
                for part in shape.parts() {
                    for _ in 0..64 {
                        let local = part.support_point(&rng.vec(1.0));
                        let p: Point3<f64> = pose * local;
                        // How far inside the bounds the sample is (negative: outside).
                        let slack = (0..3)
                            .map(|k| (p[k] - bounds.min[k]).min(bounds.max[k] - p[k]))
                            .fold(f64::INFINITY, f64::min);
                        worst_slack = worst_slack.min(slack);
                        assert!(
                            slack > -1e-12,
                            "{shape:?}: sample {p} outside swept bounds {bounds:?} by {slack:e}"
                        );
                    }
                }
            }
        }
    }
    worst_slack
}

#[test]
fn swept_bounds_hold_the_shape_over_large_turns() {
    check_swept(&mut Rng(11), std::f64::consts::PI, 0.02);
}

#[test]
fn swept_bounds_hold_the_shape_over_haptic_steps() {
    // A 1 kHz step of a hand-held tool: up to 0.05 rad and 1 mm.
    check_swept(&mut Rng(12), 0.05, 0.001);
}

#[test]
fn swept_bounds_of_a_small_turn_stay_close_to_the_end_bounds() {
    // A 6 cm probe turning by 1 mrad about its tip: the bounds grow by micrometres, not by the
    // probe's length.
    let shape = ToolShape::Probe {
        radius: 0.002,
        length: 0.06,
    };
    let pose0 = Isometry3::translation(0.3, -0.2, 0.5);
    let pose1 = pose0 * Isometry3::rotation(Vector3::new(0.001, 0.0, 0.0));
    let ends = shape.aabb(&pose0, 0.0).merged(&shape.aabb(&pose1, 0.0));
    let swept = shape.swept_aabb(&pose0, &pose1, 0.0);
    let growth = (swept.max - ends.max)
        .amax()
        .max((ends.min - swept.min).amax());
    assert!(growth < 1e-6, "grew by {growth:e} m");
    // And the margin is added on every side.
    let m = shape.swept_aabb(&pose0, &pose1, 0.001);
    assert!(((m.max - swept.max) - Vector3::repeat(0.001)).amax() < 1e-15);
}

#[test]
fn step_bounds_cover_the_previous_and_current_pose() {
    let shape = ToolShape::Sphere { radius: 0.001 };
    let mut tool = Tool::new(shape, Isometry3::translation(0.0, 0.0, 0.0)).unwrap();
    tool.set_pose(Isometry3::translation(0.01, 0.0, 0.0));
    let b = tool.step_bounds(0.0);
    assert!((b.min.x + 0.001).abs() < 1e-15 && (b.max.x - 0.011).abs() < 1e-15);
    assert!(Tool::new(ToolShape::Sphere { radius: -1.0 }, Isometry3::identity()).is_err());
}

#[cfg(feature = "scene")]
mod scene {
    use std::path::Path;

    use lancet::collide::{ToolShape, Trajectory};
    use lancet::scene::Scene;

    const BASE: &str = r#"Scene(
        name: "probe",
        mesh: Box((cells: (2, 2, 2), size: (0.02, 0.02, 0.02))),
        material: (stiffness: Material(youngs_modulus: 1e4, poisson_ratio: 0.25), mass: Density(1000.0)),
        dt: BoundFraction(0.5),
        steps: 10,
        TOOLS
    )"#;

    fn with_tools(tools: &str) -> String {
        BASE.replace("TOOLS", tools)
    }

    fn parse(tools: &str) -> lancet::Result<Scene> {
        Scene::from_ron(&with_tools(tools), Path::new("tools.ron"))
    }

    #[test]
    fn scenes_without_tools_still_parse() {
        let scene = Scene::default_scene();
        assert!(scene.tools.is_empty());
    }

    #[test]
    fn scene_tools_parse_with_keyframes_and_velocity() {
        let scene = parse(
            r#"tools: [
                (name: "probe", shape: Probe(radius: 0.002, length: 0.05),
                 trajectory: Keyframes([
                    (time: 0.0, translation: (0.01, 0.01, 0.03)),
                    (time: 0.5, translation: (0.01, 0.01, 0.018), rotation: (0.0, 0.2, 0.0)),
                 ])),
                (name: "needle", shape: Probe(radius: 0.0004, length: 0.04),
                 trajectory: Velocity(translation: (0.02, 0.01, 0.03), linear: (0.0, 0.0, -0.01))),
                (name: "jaws", shape: Grasper(jaw: (0.001, 0.002, 0.006), opening: 0.0),
                 trajectory: Keyframes([(time: 0.0)])),
                (name: "scalpel", shape: Blade(width: 0.01, length: 0.03, thickness: 0.0003),
                 trajectory: Keyframes([(time: 0.0)])),
                (name: "ball", shape: Sphere(radius: 0.003), trajectory: Keyframes([(time: 0.0)])),
            ],"#,
        )
        .expect("valid tools parse");
        assert_eq!(scene.tools.len(), 5);
        assert_eq!(
            scene.tools[0].shape,
            ToolShape::Probe {
                radius: 0.002,
                length: 0.05
            }
        );
        let Trajectory::Keyframes(k) = &scene.tools[0].trajectory else {
            panic!("keyframes expected")
        };
        assert_eq!(k[0].rotation, [0.0; 3]);
        let z = scene.tools[1].trajectory.pose_at(1.0).translation.z;
        assert!((z - 0.02).abs() < 1e-15);
    }

    fn error_of(tools: &str) -> String {
        parse(tools).unwrap_err().to_string()
    }

    #[test]
    fn scene_tool_errors_name_the_tool_and_the_problem() {
        let e = error_of(
            r#"tools: [(name: "probe", shape: Probe(radius: 0.0, length: 0.05), trajectory: Keyframes([(time: 0.0)]))],"#,
        );
        assert!(
            e.starts_with("tools.ron: tool 0 (\"probe\"): tool probe radius must be positive"),
            "{e}"
        );
        let e = error_of(
            r#"tools: [(name: "g", shape: Grasper(jaw: (0.001, -0.002, 0.006), opening: 0.0), trajectory: Keyframes([(time: 0.0)]))],"#,
        );
        assert!(
            e.contains("grasper jaw half-extent along y must be positive"),
            "{e}"
        );
        let e = error_of(
            r#"tools: [(name: "s", shape: Sphere(radius: 0.001), trajectory: Keyframes([]))],"#,
        );
        assert!(
            e.contains("tool 0 (\"s\"): trajectory has no keyframes"),
            "{e}"
        );
        let e = error_of(
            r#"tools: [(name: "s", shape: Sphere(radius: 0.001), trajectory: Keyframes([(time: 1.0), (time: 0.5)]))],"#,
        );
        assert!(
            e.contains("keyframe 1 is at time 0.5 s, not after keyframe 0 at 1 s"),
            "{e}"
        );
        let e = error_of(
            r#"tools: [
                (name: "s", shape: Sphere(radius: 0.001), trajectory: Keyframes([(time: 0.0)])),
                (name: "s", shape: Sphere(radius: 0.002), trajectory: Keyframes([(time: 0.0)])),
            ],"#,
        );
        assert!(
            e.contains("tool 1 (\"s\"): another tool has this name"),
            "{e}"
        );
        // An unknown shape is a parse error with the line.
        let e = error_of(
            r#"tools: [(name: "s", shape: Hook(radius: 0.001), trajectory: Keyframes([(time: 0.0)]))],"#,
        );
        assert!(
            e.contains("tools.ron: line") && e.contains("scene is not valid"),
            "{e}"
        );
    }
}
