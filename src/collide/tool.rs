//! Rigid tool shapes, their poses and trajectories, and conservative bounds over a motion.
//!
//! Every shape is described in its own *tool frame*: the tool's axis is the local z axis, the
//! working end (tip, cutting edge, jaw tips) is at the origin and the shaft extends along +z.
//! A pose maps the tool frame into the scene frame. Lengths are in metres.

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The shape of a rigid tool, in the tool frame (axis along local z, working end at the origin).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ToolShape {
    /// A probe or needle: a capsule whose axis runs from the origin to `(0, 0, length)`. The tip
    /// is the hemisphere centred at the origin (its apex at `z = -radius`). A needle is a thin
    /// probe.
    Probe {
        /// Radius, m.
        radius: f64,
        /// Length of the axis segment (the shaft without its two hemispherical caps), m.
        length: f64,
    },
    /// A sphere centred at the origin.
    Sphere {
        /// Radius, m.
        radius: f64,
    },
    /// A blade: the cutting quad `|x| <= width / 2`, `y = 0`, `0 <= z <= length`, given a
    /// `thickness` along y for contact. Its cutting edge is the side at `z = 0`; the cutting
    /// issue sweeps the quad ([`ToolShape::blade_quad`]).
    Blade {
        /// Width of the cutting edge, along x, m.
        width: f64,
        /// Length from the edge up the blade, along z, m.
        length: f64,
        /// Thickness across the blade, along y, m.
        thickness: f64,
    },
    /// A grasper: two jaw boxes with half-extents `jaw`, symmetric about the tool axis. Their
    /// inner faces are `opening` apart along x (zero: closed) and they reach from `z = 0` to
    /// `z = 2 * jaw[2]`.
    Grasper {
        /// Half-extents of each jaw along x, y, z, m.
        jaw: [f64; 3],
        /// Gap between the inner faces of the jaws, m; change it to open or close the grasper
        /// ([`ToolShape::set_opening`]).
        opening: f64,
    },
}

/// One convex part of a tool, in the tool frame. Every shape is a union of one or two of these;
/// the narrow phase queries each part.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ToolPart {
    /// All points within `radius` of the segment `a`–`b`.
    Capsule {
        /// One end of the axis segment.
        a: Point3<f64>,
        /// The other end.
        b: Point3<f64>,
        /// Radius, m.
        radius: f64,
    },
    /// A ball.
    Ball {
        /// Centre.
        centre: Point3<f64>,
        /// Radius, m.
        radius: f64,
    },
    /// A box aligned with the tool frame's axes.
    Box {
        /// Centre.
        centre: Point3<f64>,
        /// Half-extents along the tool frame's x, y, z, m.
        half_extents: Vector3<f64>,
    },
}

impl ToolPart {
    /// The centre of the part's bounding sphere.
    pub fn centre(&self) -> Point3<f64> {
        match *self {
            ToolPart::Capsule { a, b, .. } => nalgebra::center(&a, &b),
            ToolPart::Ball { centre, .. } | ToolPart::Box { centre, .. } => centre,
        }
    }

    /// The radius of the part's bounding sphere about [`ToolPart::centre`].
    pub fn bounding_radius(&self) -> f64 {
        match *self {
            ToolPart::Capsule { a, b, radius } => 0.5 * (b - a).norm() + radius,
            ToolPart::Ball { radius, .. } => radius,
            ToolPart::Box { half_extents, .. } => half_extents.norm(),
        }
    }

    /// The point of the part farthest along `dir` (any nonzero length), in the tool frame.
    /// Every such point is on the surface; the bounds tests sample shapes with it.
    pub fn support_point(&self, dir: &Vector3<f64>) -> Point3<f64> {
        let unit = dir.try_normalize(0.0).unwrap_or_else(Vector3::z);
        match *self {
            ToolPart::Capsule { a, b, radius } => {
                let end = if (b - a).dot(&unit) > 0.0 { b } else { a };
                end + unit * radius
            }
            ToolPart::Ball { centre, radius } => centre + unit * radius,
            ToolPart::Box {
                centre,
                half_extents,
            } => centre + half_extents.zip_map(&unit, |h, d| if d >= 0.0 { h } else { -h }),
        }
    }

    /// The exact axis-aligned bounds of the part placed at `pose`.
    pub fn aabb(&self, pose: &Isometry3<f64>) -> Aabb {
        match *self {
            ToolPart::Capsule { a, b, radius } => {
                let (wa, wb) = (pose * a, pose * b);
                let r = Vector3::repeat(radius);
                Aabb {
                    min: wa.inf(&wb) - r,
                    max: wa.sup(&wb) + r,
                }
            }
            ToolPart::Ball { centre, radius } => {
                let c = pose * centre;
                let r = Vector3::repeat(radius);
                Aabb {
                    min: c - r,
                    max: c + r,
                }
            }
            ToolPart::Box {
                centre,
                half_extents,
            } => {
                // The extent of a rotated box along each world axis is |R| times its
                // half-extents.
                let c = pose * centre;
                let rot = pose.rotation.to_rotation_matrix();
                let ext = rot.matrix().abs() * half_extents;
                Aabb {
                    min: c - ext,
                    max: c + ext,
                }
            }
        }
    }
}

/// An axis-aligned box in the scene frame, float64, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Smallest corner.
    pub min: Point3<f64>,
    /// Largest corner.
    pub max: Point3<f64>,
}

impl Aabb {
    /// The smallest box holding both.
    pub fn merged(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.inf(&other.min),
            max: self.max.sup(&other.max),
        }
    }

    /// The box grown by `margin` on every side.
    pub fn inflated(&self, margin: f64) -> Aabb {
        let m = Vector3::repeat(margin);
        Aabb {
            min: self.min - m,
            max: self.max + m,
        }
    }

    /// The part of space in both boxes (its min may exceed its max where they do not meet).
    pub fn intersection(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.sup(&other.min),
            max: self.max.inf(&other.max),
        }
    }

    /// Whether `p` is inside or on the box.
    pub fn contains(&self, p: &Point3<f64>) -> bool {
        (0..3).all(|i| self.min[i] <= p[i] && p[i] <= self.max[i])
    }

    /// Whether the two boxes share a point.
    pub fn intersects(&self, other: &Aabb) -> bool {
        (0..3).all(|i| self.min[i] <= other.max[i] && other.min[i] <= self.max[i])
    }
}

fn check_size(what: &str, value: f64, allow_zero: bool) -> Result<()> {
    let ok = value.is_finite() && (value > 0.0 || (allow_zero && value == 0.0));
    if ok {
        Ok(())
    } else {
        let need = if allow_zero {
            "zero or positive"
        } else {
            "positive"
        };
        Err(Error::Options(format!(
            "tool {what} must be {need} and finite, got {value} m"
        )))
    }
}

impl ToolShape {
    /// Check that every size is positive and finite (a grasper's opening may be zero).
    pub fn validate(&self) -> Result<()> {
        match *self {
            ToolShape::Probe { radius, length } => {
                check_size("probe radius", radius, false)?;
                check_size("probe length", length, false)
            }
            ToolShape::Sphere { radius } => check_size("sphere radius", radius, false),
            ToolShape::Blade {
                width,
                length,
                thickness,
            } => {
                check_size("blade width", width, false)?;
                check_size("blade length", length, false)?;
                check_size("blade thickness", thickness, false)
            }
            ToolShape::Grasper { jaw, opening } => {
                for (axis, h) in ["x", "y", "z"].iter().zip(jaw) {
                    check_size(&format!("grasper jaw half-extent along {axis}"), h, false)?;
                }
                check_size("grasper opening", opening, true)
            }
        }
    }

    /// Open or close a grasper: `opening` is the gap between the jaws' inner faces, m.
    /// Refused for other shapes and for a negative or non-finite opening.
    pub fn set_opening(&mut self, opening: f64) -> Result<()> {
        match self {
            ToolShape::Grasper { opening: o, .. } => {
                check_size("grasper opening", opening, true)?;
                *o = opening;
                Ok(())
            }
            _ => Err(Error::Options(
                "only a grasper has an opening; this tool is not a grasper".into(),
            )),
        }
    }

    /// The convex parts of the shape, in the tool frame: one for every shape but the grasper,
    /// which has a jaw on each side of the axis (negative x first).
    pub fn parts(&self) -> Vec<ToolPart> {
        match *self {
            ToolShape::Probe { radius, length } => vec![ToolPart::Capsule {
                a: Point3::origin(),
                b: Point3::new(0.0, 0.0, length),
                radius,
            }],
            ToolShape::Sphere { radius } => vec![ToolPart::Ball {
                centre: Point3::origin(),
                radius,
            }],
            ToolShape::Blade {
                width,
                length,
                thickness,
            } => vec![ToolPart::Box {
                centre: Point3::new(0.0, 0.0, 0.5 * length),
                half_extents: Vector3::new(0.5 * width, 0.5 * thickness, 0.5 * length),
            }],
            ToolShape::Grasper { jaw, opening } => {
                let h = Vector3::from(jaw);
                let x = 0.5 * opening + h.x;
                [-x, x]
                    .into_iter()
                    .map(|cx| ToolPart::Box {
                        centre: Point3::new(cx, 0.0, h.z),
                        half_extents: h,
                    })
                    .collect()
            }
        }
    }

    /// Centre and radius (in the tool frame) of a sphere holding the whole shape.
    pub fn bounding_sphere(&self) -> (Point3<f64>, f64) {
        match *self {
            ToolShape::Probe { radius, length } => {
                (Point3::new(0.0, 0.0, 0.5 * length), 0.5 * length + radius)
            }
            ToolShape::Sphere { radius } => (Point3::origin(), radius),
            ToolShape::Blade {
                width,
                length,
                thickness,
            } => (
                Point3::new(0.0, 0.0, 0.5 * length),
                0.5 * Vector3::new(width, thickness, length).norm(),
            ),
            ToolShape::Grasper { jaw, opening } => (
                Point3::new(0.0, 0.0, jaw[2]),
                Vector3::new(0.5 * opening + 2.0 * jaw[0], jaw[1], jaw[2]).norm(),
            ),
        }
    }

    /// The cutting quad of a blade at `pose` (edge first: the two corners at `z = 0`, then the
    /// two at `z = length`), in the scene frame; `None` for other shapes.
    pub fn blade_quad(&self, pose: &Isometry3<f64>) -> Option<[Point3<f64>; 4]> {
        match *self {
            ToolShape::Blade { width, length, .. } => {
                let w = 0.5 * width;
                Some([
                    pose * Point3::new(-w, 0.0, 0.0),
                    pose * Point3::new(w, 0.0, 0.0),
                    pose * Point3::new(w, 0.0, length),
                    pose * Point3::new(-w, 0.0, length),
                ])
            }
            _ => None,
        }
    }

    /// The exact axis-aligned bounds of the shape at `pose`, grown by `margin` (m).
    pub fn aabb(&self, pose: &Isometry3<f64>, margin: f64) -> Aabb {
        let parts = self.parts();
        let mut bounds = parts[0].aabb(pose);
        for p in &parts[1..] {
            bounds = bounds.merged(&p.aabb(pose));
        }
        bounds.inflated(margin)
    }

    /// Conservative bounds of the shape over the motion from `pose0` to `pose1`, grown by
    /// `margin` (m).
    ///
    /// The motion between the poses is the one a [`Trajectory`] makes within a step: the tool
    /// origin moves on the straight line, the rotation turns at a constant rate about a fixed
    /// axis (slerp). Two bounds hold every point of the shape over that motion, and the result is
    /// their intersection:
    ///
    /// - the hull of the bounds at both ends, grown by how far a point at distance `rho` from
    ///   the tool origin can stray from the straight line between its two end positions while it
    ///   turns by the angle `theta`: `rho * (1 - cos(theta / 2) + theta / 2 - sin(theta / 2))`
    ///   (tight for small turns, as in a haptic loop);
    /// - the bounding sphere swept along its centre's path: the straight move of the tool origin
    ///   plus the chord of the centre's arc, grown by the arc's sagitta and the sphere radius
    ///   (tight for large turns).
    pub fn swept_aabb(&self, pose0: &Isometry3<f64>, pose1: &Isometry3<f64>, margin: f64) -> Aabb {
        let ends = self.aabb(pose0, 0.0).merged(&self.aabb(pose1, 0.0));
        let theta = pose0.rotation.angle_to(&pose1.rotation);
        if theta == 0.0 {
            // A pure translation of a convex part sweeps the hull of its two end positions;
            // the union of parts keeps that property part by part.
            return ends.inflated(margin);
        }
        let (centre, radius) = self.bounding_sphere();
        let rho = centre.coords.norm() + radius;
        let half = 0.5 * theta;
        let stray = rho * ((1.0 - half.cos()) + (half - half.sin()));
        let by_points = ends.inflated(stray);

        let (t0, t1) = (pose0.translation.vector, pose1.translation.vector);
        let (a0, a1) = (
            pose0.rotation * centre.coords,
            pose1.rotation * centre.coords,
        );
        let sagitta = centre.coords.norm() * (1.0 - half.cos());
        let grow = Vector3::repeat(sagitta + radius);
        let by_sphere = Aabb {
            min: Point3::from(t0.inf(&t1) + a0.inf(&a1) - grow),
            max: Point3::from(t0.sup(&t1) + a0.sup(&a1) + grow),
        };
        by_points.intersection(&by_sphere).inflated(margin)
    }
}

/// A rigid tool: a shape with its current pose and the pose of the previous step.
#[derive(Debug, Clone, PartialEq)]
pub struct Tool {
    /// The shape, in the tool frame.
    pub shape: ToolShape,
    pose: Isometry3<f64>,
    previous: Isometry3<f64>,
}

impl Tool {
    /// A tool at rest at `pose`; refused if a size is not positive and finite.
    pub fn new(shape: ToolShape, pose: Isometry3<f64>) -> Result<Tool> {
        shape.validate()?;
        Ok(Tool {
            shape,
            pose,
            previous: pose,
        })
    }

    /// Move the tool: call this once per step with the new pose (from a haptic device, or from
    /// [`Trajectory::pose_at`]). The pose it replaces becomes the previous pose, so that
    /// [`Tool::step_bounds`] covers the step's motion.
    pub fn set_pose(&mut self, pose: Isometry3<f64>) {
        self.previous = self.pose;
        self.pose = pose;
    }

    /// The current pose.
    pub fn pose(&self) -> &Isometry3<f64> {
        &self.pose
    }

    /// The pose before the last [`Tool::set_pose`].
    pub fn previous_pose(&self) -> &Isometry3<f64> {
        &self.previous
    }

    /// Bounds of the shape at `pose`, grown by `margin`; see [`ToolShape::aabb`].
    pub fn aabb(&self, pose: &Isometry3<f64>, margin: f64) -> Aabb {
        self.shape.aabb(pose, margin)
    }

    /// Conservative bounds over the motion from `pose0` to `pose1`; see
    /// [`ToolShape::swept_aabb`].
    pub fn swept_aabb(&self, pose0: &Isometry3<f64>, pose1: &Isometry3<f64>, margin: f64) -> Aabb {
        self.shape.swept_aabb(pose0, pose1, margin)
    }

    /// Conservative bounds over the last step, from the previous pose to the current one.
    pub fn step_bounds(&self, margin: f64) -> Aabb {
        self.shape.swept_aabb(&self.previous, &self.pose, margin)
    }
}

/// A pose at a time: translation in metres, rotation as a rotation vector (axis times angle,
/// radians) so that scene files can write it as three numbers.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Time, s.
    pub time: f64,
    /// Position of the tool origin in the scene frame, m.
    #[serde(default)]
    pub translation: [f64; 3],
    /// Orientation of the tool frame: rotation vector (unit axis times angle in radians).
    #[serde(default)]
    pub rotation: [f64; 3],
}

impl Keyframe {
    /// The keyframe's pose.
    pub fn pose(&self) -> Isometry3<f64> {
        pose_from(self.translation, self.rotation)
    }
}

fn pose_from(translation: [f64; 3], rotation: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::from(Vector3::from(translation)),
        UnitQuaternion::from_scaled_axis(Vector3::from(rotation)),
    )
}

/// How a scene moves a tool.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Trajectory {
    /// Keyframed poses at increasing times: the translation is interpolated linearly and the
    /// rotation by slerp (the shorter way round; put keyframes less than half a turn apart).
    /// Before the first keyframe the tool stays at the first pose, after the last at the last.
    Keyframes(Vec<Keyframe>),
    /// A constant scripted velocity from a starting pose at time 0: the tool origin moves at
    /// `linear` (m/s) and the tool turns at `angular` (rad/s, a rotation vector in the scene
    /// frame) about its own origin. Before time 0 the tool stays at the start.
    Velocity {
        /// Starting position of the tool origin, m.
        #[serde(default)]
        translation: [f64; 3],
        /// Starting orientation, rotation vector (radians).
        #[serde(default)]
        rotation: [f64; 3],
        /// Linear velocity, m/s.
        #[serde(default)]
        linear: [f64; 3],
        /// Angular velocity, rad/s (a rotation vector per second, scene frame).
        #[serde(default)]
        angular: [f64; 3],
    },
}

impl Trajectory {
    /// Check that there is at least one keyframe, that times increase strictly and that every
    /// number is finite. The message says which keyframe is wrong.
    pub fn validate(&self) -> Result<()> {
        let finite = |what: &str, v: &[f64]| {
            if v.iter().all(|x| x.is_finite()) {
                Ok(())
            } else {
                Err(Error::Options(format!(
                    "trajectory {what} must be finite, got {v:?}"
                )))
            }
        };
        match self {
            Trajectory::Keyframes(frames) => {
                if frames.is_empty() {
                    return Err(Error::Options(
                        "trajectory has no keyframes; give at least one (one keyframe holds \
                         the tool still)"
                            .into(),
                    ));
                }
                for (i, k) in frames.iter().enumerate() {
                    finite(&format!("keyframe {i} time"), &[k.time])?;
                    finite(&format!("keyframe {i} translation"), &k.translation)?;
                    finite(&format!("keyframe {i} rotation"), &k.rotation)?;
                    if i > 0 && k.time <= frames[i - 1].time {
                        return Err(Error::Options(format!(
                            "keyframe {i} is at time {} s, not after keyframe {} at {} s; list \
                             keyframes in increasing time",
                            k.time,
                            i - 1,
                            frames[i - 1].time
                        )));
                    }
                }
                Ok(())
            }
            Trajectory::Velocity {
                translation,
                rotation,
                linear,
                angular,
            } => {
                finite("translation", translation)?;
                finite("rotation", rotation)?;
                finite("linear velocity", linear)?;
                finite("angular velocity", angular)
            }
        }
    }

    /// The pose at time `t` (s), clamped to the first and last keyframes (a velocity
    /// trajectory is clamped at time 0). An empty keyframe list, which
    /// [`Trajectory::validate`] refuses, gives the identity pose; keyframes out of order give
    /// an unspecified pose, never a panic.
    pub fn pose_at(&self, t: f64) -> Isometry3<f64> {
        match self {
            Trajectory::Keyframes(frames) => {
                let (Some(first), Some(last)) = (frames.first(), frames.last()) else {
                    return Isometry3::identity();
                };
                if t.is_nan() || t <= first.time {
                    return first.pose();
                }
                if t >= last.time {
                    return last.pose();
                }
                // The first keyframe after t; it exists and is not the first, by the clamps
                // (there are at least two keyframes here). The clamp keeps the indices valid
                // even for keyframes out of order, which `validate` refuses.
                let j = frames
                    .partition_point(|k| k.time <= t)
                    .clamp(1, frames.len() - 1);
                let (k0, k1) = (&frames[j - 1], &frames[j]);
                let s = (t - k0.time) / (k1.time - k0.time);
                let (p0, p1) = (k0.pose(), k1.pose());
                // `a + (b - a) s` rather than nalgebra's `a (1 - s) + b s`: a coordinate that
                // does not change between keyframes stays exactly as written (a blade kept in
                // the plane of grid nodes cuts exactly through them).
                let (a, b) = (p0.translation.vector, p1.translation.vector);
                let translation = a + (b - a) * s;
                Isometry3::from_parts(
                    Translation3::from(translation),
                    slerp(&p0.rotation, &p1.rotation, s),
                )
            }
            Trajectory::Velocity {
                translation,
                rotation,
                linear,
                angular,
            } => {
                let t = t.max(0.0);
                let start = pose_from(*translation, *rotation);
                let turn = UnitQuaternion::from_scaled_axis(Vector3::from(*angular) * t);
                Isometry3::from_parts(
                    Translation3::from(start.translation.vector + Vector3::from(*linear) * t),
                    turn * start.rotation,
                )
            }
        }
    }
}

/// Slerp that never panics: nalgebra's `slerp` panics when the two rotations are nearly equal
/// (the angle between them is too small to divide by), where any point between them will do.
fn slerp(q0: &UnitQuaternion<f64>, q1: &UnitQuaternion<f64>, s: f64) -> UnitQuaternion<f64> {
    if q0 == q1 {
        return *q0;
    }
    let nearer = if s < 0.5 { *q0 } else { *q1 };
    q0.try_slerp(q1, s, 1e-12).unwrap_or(nearer)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grasper_jaws_sit_on_both_sides_of_the_axis_with_the_given_opening() {
        let g = ToolShape::Grasper {
            jaw: [0.001, 0.002, 0.005],
            opening: 0.004,
        };
        let parts = g.parts();
        assert_eq!(parts.len(), 2);
        let inner: Vec<f64> = parts
            .iter()
            .map(|p| p.support_point(&Vector3::new(-p.centre().x, 0.0, 0.0)).x)
            .collect();
        assert!((inner[0] + 0.002).abs() < 1e-15 && (inner[1] - 0.002).abs() < 1e-15);
    }

    #[test]
    fn probe_bounds_are_exact_when_axis_aligned() {
        let probe = ToolShape::Probe {
            radius: 0.001,
            length: 0.01,
        };
        let pose = Isometry3::translation(0.3, -0.2, 0.5);
        let b = probe.aabb(&pose, 0.0);
        assert!((b.min - Point3::new(0.299, -0.201, 0.499)).norm() < 1e-12);
        assert!((b.max - Point3::new(0.301, -0.199, 0.511)).norm() < 1e-12);
    }

    #[test]
    fn nearly_equal_rotations_interpolate_without_panicking() {
        let q0 = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 1e-9));
        let q1 = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 1.1e-9));
        let q = slerp(&q0, &q1, 0.5);
        assert!(q.angle_to(&q0) < 1e-8);
    }

    #[test]
    fn bad_sizes_are_refused_with_the_size_named() {
        let e = ToolShape::Blade {
            width: 0.01,
            length: 0.02,
            thickness: 0.0,
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(e.contains("blade thickness must be positive"), "{e}");
        let mut s = ToolShape::Sphere { radius: 0.001 };
        assert!(s.set_opening(0.001).is_err());
    }
}
