//! Haptic-rate force: a virtual coupling between a haptic device and a tool proxy.
//!
//! The contact response moves tissue out of a tool by position correction, and the force it
//! reports is that correction's `-sum m dx / h^2` ([`super::ToolStep::force`]). That is an
//! impulse per step squared: at first contact a tool driven straight by a device moves the
//! surface by a step's worth of penetration at once, and the force jumps by orders of
//! magnitude from one step to the next (28,070 -> 126,309 -> 8,740 N were measured). A device
//! cannot render that.
//!
//! The coupling puts a spring-damper between the device and a *proxy*, a point of mass `m`
//! that is the tool in the simulation. Each step of length `h` the proxy is pulled by the
//! spring (stiffness `k`, damping `b`) toward the device and pushed by the tissue's reaction
//! `F_t` from the step before, integrated implicitly in the coupling:
//!
//! ```text
//! (m + h b + h^2 k) v' = m v + h (k (x_d - x) + b v_d + F_t),    x' = x + h v'
//! ```
//!
//! and the device is sent the coupling force, which pulls it toward the proxy,
//!
//! ```text
//! F = k (x - x_d) + b (v - v_d).
//! ```
//!
//! Positions are continuous, so `F` changes from one step to the next by no more than the
//! coupling allows: `|dF| <= k (|dx_d| + |dx|) + b (|dv_d| + |dv|)`, whatever the tissue did.
//! When the proxy comes to rest against the tissue, the spring balances the reaction and `F`
//! is the tissue's reaction on the tool (in a steady press, the elastic force of the tissue
//! pressed; holding a block up, its weight).
//!
//! # Stability
//!
//! - The coupling itself is integrated implicitly: stable for any `k`, `b`, `m` and step `h`.
//! - The tissue's reaction enters explicitly (from the step before). A proxy that moves into
//!   the tissue by `d` in a step gets back about `M d / h^2` from the surface mass `M` it moved,
//!   which moves it back by `M d / (m + h b + h^2 k)` at the next step: the exchange dies out
//!   only when **`m + h b + h^2 k > M`**, the mass of the surface nodes the tool pushes in one
//!   step. With a light proxy this is a bound on the coupling stiffness against the step:
//!   `k > M / h^2` (at `h` = 1 ms and a gram of tissue under the tool, `k` > 1000 N/m). Make
//!   the proxy heavier than the tissue it touches and any `k` is stable.
//! - The device side: a coupling rendered at a sample period `T` (1 ms at 1 kHz) with a
//!   zero-order hold is passive when the device's own damping `B` satisfies Colgate's
//!   condition **`B > k T / 2 + b`**; stiffer couplings than `2 (B - b) / T` buzz.
//!
//! Only the translation is coupled: the proxy takes the device's orientation.

use nalgebra::{Isometry3, Vector3};

use crate::error::{Error, Result};

/// A spring-damper between a haptic device and a tool proxy; see the module documentation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VirtualCoupling {
    /// Spring stiffness `k`, N/m.
    pub stiffness: f64,
    /// Damping `b` on the relative velocity, N s/m.
    pub damping: f64,
    /// Proxy mass `m`, kg (zero for a massless proxy: then `h^2 k` must exceed the tissue
    /// mass the tool pushes in one step).
    pub proxy_mass: f64,
}

/// Where a proxy is and how fast it moves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProxyState {
    /// Position, m.
    pub position: Vector3<f64>,
    /// Velocity, m/s.
    pub velocity: Vector3<f64>,
}

impl ProxyState {
    /// A proxy at rest at `position`.
    pub fn at_rest(position: Vector3<f64>) -> Self {
        ProxyState {
            position,
            velocity: Vector3::zeros(),
        }
    }
}

impl VirtualCoupling {
    /// Refused unless the stiffness is positive and the damping and mass are zero or positive,
    /// all finite.
    pub fn validate(&self) -> Result<()> {
        let ok = |x: f64| x.is_finite() && x >= 0.0;
        if !(ok(self.stiffness) && self.stiffness > 0.0 && ok(self.damping) && ok(self.proxy_mass))
        {
            return Err(Error::Options(format!(
                "virtual coupling: stiffness must be positive and damping and proxy mass zero \
                 or positive, all finite; got stiffness {}, damping {}, proxy mass {}",
                self.stiffness, self.damping, self.proxy_mass
            )));
        }
        Ok(())
    }

    /// The force on the device at `device` moving at `device_velocity`, with the proxy in
    /// `proxy`, N: it pulls the device toward the proxy. A haptic loop faster than the
    /// simulation calls this at its own rate with the latest proxy and the device's latest
    /// pose.
    pub fn force(
        &self,
        proxy: &ProxyState,
        device: &Isometry3<f64>,
        device_velocity: &Vector3<f64>,
    ) -> Vector3<f64> {
        self.stiffness * (proxy.position - device.translation.vector)
            + self.damping * (proxy.velocity - device_velocity)
    }

    /// The proxy after a step of `h`, pulled toward `device` and pushed by `contact` (the
    /// tissue's reaction on the tool at the last step, N); implicit in the coupling.
    pub fn advance(
        &self,
        proxy: &ProxyState,
        device: &Isometry3<f64>,
        device_velocity: &Vector3<f64>,
        contact: &Vector3<f64>,
        h: f64,
    ) -> ProxyState {
        let (k, b, m) = (self.stiffness, self.damping, self.proxy_mass);
        let pull = k * (device.translation.vector - proxy.position) + b * device_velocity;
        let velocity = (m * proxy.velocity + h * (pull + contact)) / (m + h * b + h * h * k);
        ProxyState {
            position: proxy.position + h * velocity,
            velocity,
        }
    }

    /// The largest change of the force on the device over one step that the coupling allows,
    /// N, given how far the device moved (`device_motion`, m) and how much its velocity changed
    /// (`device_dv`, m/s), and the same for the proxy: `k (|dx_d| + |dx|) + b (|dv_d| + |dv|)`.
    pub fn increment_bound(
        &self,
        device_motion: f64,
        device_dv: f64,
        proxy_motion: f64,
        proxy_dv: f64,
    ) -> f64 {
        self.stiffness * (device_motion + proxy_motion) + self.damping * (device_dv + proxy_dv)
    }
}
