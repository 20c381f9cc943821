//! The float64 reference engine: serial, one spring at a time, no tricks. Everything faster is
//! checked against it.

use super::{Engine, Integrator, SimConfig};
use crate::model::PackedModel;

type V3 = [f64; 3];

/// Float64 serial engine.
pub struct ReferenceEngine {
    model: PackedModel,
    dt: f64,
    integrator: Integrator,
    x: Vec<V3>,
    /// Verlet: the previous positions. Symplectic Euler: the velocities.
    second: Vec<V3>,
    force: Vec<V3>,
}

impl ReferenceEngine {
    /// Start at rest at the rest positions.
    pub fn new(model: &PackedModel, config: SimConfig) -> Self {
        let x = model.rest.clone();
        let second = match config.integrator {
            Integrator::Verlet => x.clone(),
            Integrator::SymplecticEuler => vec![[0.0; 3]; x.len()],
        };
        ReferenceEngine {
            model: model.clone(),
            dt: config.dt,
            integrator: config.integrator,
            force: vec![[0.0; 3]; x.len()],
            x,
            second,
        }
    }

    fn velocity(&self, i: usize) -> V3 {
        match self.integrator {
            Integrator::Verlet => {
                let (x, p) = (self.x[i], self.second[i]);
                [
                    (x[0] - p[0]) / self.dt,
                    (x[1] - p[1]) / self.dt,
                    (x[2] - p[2]) / self.dt,
                ]
            }
            Integrator::SymplecticEuler => self.second[i],
        }
    }

    /// Spring forces (elastic and damping along each spring) at the current state.
    fn spring_forces(&mut self) {
        for f in &mut self.force {
            *f = [0.0; 3];
        }
        for s in self.model.springs() {
            let (a, b) = (s.nodes[0] as usize, s.nodes[1] as usize);
            let d = sub(self.x[b], self.x[a]);
            let l = norm(d);
            if l == 0.0 {
                // Coincident nodes: no direction to push along.
                continue;
            }
            let u = scale(d, 1.0 / l);
            let dv = sub(self.velocity(b), self.velocity(a));
            let magnitude = s.stiffness * (l - s.rest_length) + s.damping * dot(dv, u);
            let f = scale(u, magnitude);
            self.force[a] = add(self.force[a], f);
            self.force[b] = sub(self.force[b], f);
        }
    }
}

impl Engine for ReferenceEngine {
    fn step(&mut self, steps: u32) {
        let (h, g, alpha) = (self.dt, self.model.gravity, self.model.mass_damping);
        for _ in 0..steps {
            self.spring_forces();
            for i in 0..self.x.len() {
                if self.model.fixed[i] {
                    continue;
                }
                let v = self.velocity(i);
                let m = self.model.mass[i];
                let f = self.force[i];
                let a = [
                    f[0] / m + g[0] - alpha * v[0],
                    f[1] / m + g[1] - alpha * v[1],
                    f[2] / m + g[2] - alpha * v[2],
                ];
                match self.integrator {
                    Integrator::Verlet => {
                        let x = self.x[i];
                        let next = [
                            x[0] + (x[0] - self.second[i][0]) + h * h * a[0],
                            x[1] + (x[1] - self.second[i][1]) + h * h * a[1],
                            x[2] + (x[2] - self.second[i][2]) + h * h * a[2],
                        ];
                        self.second[i] = x;
                        self.x[i] = next;
                    }
                    Integrator::SymplecticEuler => {
                        let v = add(v, scale(a, h));
                        self.second[i] = v;
                        self.x[i] = add(self.x[i], scale(v, h));
                    }
                }
            }
        }
    }

    fn positions(&self) -> Vec<V3> {
        self.x.clone()
    }

    fn velocities(&self) -> Vec<V3> {
        (0..self.x.len()).map(|i| self.velocity(i)).collect()
    }

    fn name(&self) -> String {
        "cpu-reference-f64".into()
    }

    fn memory(&self) -> super::EngineMemory {
        let (n, m) = (self.x.len() as u64, self.model.springs().len() as u64);
        let spring = std::mem::size_of::<crate::model::PackedSpring>() as u64;
        let v3 = std::mem::size_of::<V3>() as u64;
        let buffers = vec![
            ("springs".to_string(), m * spring),
            ("positions".to_string(), n * v3),
            ("previous (verlet) or velocities".to_string(), n * v3),
            ("forces".to_string(), n * v3),
            ("masses".to_string(), n * 8),
            ("fixed flags".to_string(), n),
        ];
        // A step reads the springs, masses and flags, and reads and writes positions, the
        // second state and the forces.
        let bytes_per_step = m * spring + n * (8 + 1) + 2 * 3 * n * v3;
        super::EngineMemory {
            stats: crate::layout::MemoryStats::new(buffers, 0, n as usize, m as usize),
            bytes_per_step,
        }
    }

    fn correct_positions(&mut self, nodes: &[u32], positions: &[V3]) -> crate::Result<()> {
        super::check_correction(nodes, positions, self.x.len())?;
        for (&i, &p) in nodes.iter().zip(positions) {
            let i = i as usize;
            if self.model.fixed[i] {
                continue;
            }
            if self.integrator == Integrator::SymplecticEuler {
                let moved = sub(p, self.x[i]);
                self.second[i] = add(self.second[i], scale(moved, 1.0 / self.dt));
            }
            self.x[i] = p;
        }
        Ok(())
    }

    fn set_time_step(&mut self, dt: f64) -> crate::Result<super::PatchCost> {
        // Exactly what an engine built at `dt` and given this state would hold.
        let (x, v) = self.state();
        self.dt = dt;
        self.set_state(&x, &v);
        Ok(super::PatchCost::parameters_only(
            std::mem::size_of::<f64>() as u64,
            self.memory().stats.total,
        ))
    }

    fn set_state(&mut self, positions: &[V3], velocities: &[V3]) {
        for i in 0..self.x.len() {
            let (x, v) = if self.model.fixed[i] {
                (self.model.rest[i], [0.0; 3])
            } else {
                (positions[i], velocities[i])
            };
            self.x[i] = x;
            self.second[i] = match self.integrator {
                Integrator::Verlet => sub(x, scale(v, self.dt)),
                Integrator::SymplecticEuler => v,
            };
        }
    }
}

fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: V3, s: f64) -> V3 {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: V3) -> f64 {
    dot(a, a).sqrt()
}
