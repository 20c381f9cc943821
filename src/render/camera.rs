//! The camera of the pictures: a perspective view fitted to a bounding box.
//!
//! [`Camera::fit`] looks at the centre of the box from a direction given by an azimuth about
//! the up axis and an elevation above the plane across it, at the distance where the box's
//! bounding sphere just fits the narrower of the two fields of view (so the whole box shows
//! from any direction), divided by a zoom factor. Azimuth 0 looks along the first axis across
//! up (x, or y when up is along x) from its positive side; positive azimuths turn
//! counter-clockwise seen from above.

use nalgebra::{Isometry3, Matrix4, Point3, Vector3};

/// How the camera looks at the box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Degrees about the up axis.
    pub azimuth: f64,
    /// Degrees above the plane across the up axis (clamped to ±89).
    pub elevation: f64,
    /// Larger than 1 moves closer (the box fills more than the picture), smaller moves away.
    pub zoom: f64,
    /// Vertical field of view, degrees.
    pub fov_y: f64,
}

impl Default for View {
    /// From the front right, 25 degrees above, the box just inside the picture.
    fn default() -> Self {
        View {
            azimuth: -60.0,
            elevation: 25.0,
            zoom: 1.0,
            fov_y: 30.0,
        }
    }
}

/// A perspective camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Where it is.
    pub eye: Point3<f64>,
    /// What it looks at.
    pub target: Point3<f64>,
    /// Up in the picture.
    pub up: Vector3<f64>,
    /// Vertical field of view, radians.
    pub fov_y: f64,
    /// Width over height of the picture.
    pub aspect: f64,
    /// Nearest distance drawn.
    pub near: f64,
    /// Farthest distance drawn.
    pub far: f64,
}

impl Camera {
    /// A camera looking at the box `lo`–`hi` as `view` says, `up` up, for a picture of
    /// width over height `aspect`. A zero or non-finite `up` is taken as +z.
    pub fn fit(lo: [f64; 3], hi: [f64; 3], up: Vector3<f64>, view: &View, aspect: f64) -> Camera {
        let up = up
            .try_normalize(0.0)
            .filter(|u| u.iter().all(|c| c.is_finite()))
            .unwrap_or_else(Vector3::z);
        let (lo, hi) = (Point3::from(lo), Point3::from(hi));
        let target = nalgebra::center(&lo, &hi);
        // A box of no size (one node) still gets a finite view.
        let radius = (0.5 * (hi - lo).norm()).max(1e-9);
        let across = if up.x.abs() < 0.9 {
            Vector3::x()
        } else {
            Vector3::y()
        };
        let e1 = (across - up * across.dot(&up)).normalize();
        let e2 = up.cross(&e1);
        let (az, el) = (
            view.azimuth.to_radians(),
            view.elevation.clamp(-89.0, 89.0).to_radians(),
        );
        let direction = (e1 * az.cos() + e2 * az.sin()) * el.cos() + up * el.sin();
        let fov_y = view.fov_y.clamp(1.0, 170.0).to_radians();
        let half_x = ((0.5 * fov_y).tan() * aspect).atan();
        let half = (0.5 * fov_y).min(half_x);
        let zoom = if view.zoom > 0.0 && view.zoom.is_finite() {
            view.zoom
        } else {
            1.0
        };
        let distance = radius / half.sin() / zoom;
        Camera {
            eye: target + direction * distance,
            target,
            up,
            fov_y,
            aspect,
            // Room for the tissue to move out of its rest box (a piece cut free falls).
            near: (distance - 3.0 * radius).max(0.01 * distance),
            far: distance + 6.0 * radius,
        }
    }

    /// The view-projection matrix for positions relative to `origin` (the vertex buffers hold
    /// float32 offsets from it, so that a scene far from the origin keeps its precision), with
    /// wgpu's clip depth from 0 at `near` to 1 at `far`.
    pub fn view_projection(&self, origin: Point3<f64>) -> Matrix4<f64> {
        let shift = Vector3::from(origin.coords);
        let view = Isometry3::look_at_rh(&(self.eye - shift), &(self.target - shift), &self.up);
        let f = 1.0 / (0.5 * self.fov_y).tan();
        let (n, far) = (self.near, self.far);
        #[rustfmt::skip]
        let projection = Matrix4::new(
            f / self.aspect, 0.0, 0.0, 0.0,
            0.0, f, 0.0, 0.0,
            0.0, 0.0, far / (n - far), n * far / (n - far),
            0.0, 0.0, -1.0, 0.0,
        );
        projection * view.to_homogeneous()
    }

    /// Where `p` lands in a picture of `width` by `height` pixels: x from the left, y from the
    /// top, in pixels (continuous), and its clip depth; `None` behind the camera.
    pub fn project(&self, p: [f64; 3], width: u32, height: u32) -> Option<([f64; 2], f64)> {
        let m = self.view_projection(Point3::origin());
        let c = m * nalgebra::Vector4::new(p[0], p[1], p[2], 1.0);
        if c.w <= 0.0 {
            return None;
        }
        let (x, y, z) = (c.x / c.w, c.y / c.w, c.z / c.w);
        Some((
            [
                0.5 * (x + 1.0) * width as f64,
                0.5 * (1.0 - y) * height as f64,
            ],
            z,
        ))
    }

    /// The direction the light comes from: over the viewer's shoulder, up and to the left of
    /// the line of sight, so that faces turned to the camera are lit and their slopes differ.
    pub fn light_direction(&self) -> Vector3<f64> {
        let back = (self.eye - self.target).normalize();
        let right = self
            .up
            .cross(&back)
            .try_normalize(0.0)
            .unwrap_or_else(Vector3::x);
        (back + 0.5 * self.up - 0.35 * right).normalize()
    }
}
