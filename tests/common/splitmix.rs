//! SplitMix64, a small seeded generator for the narrow-phase tests (so that failures
//! reproduce), and the random millimetre triangles they are built from.
#![allow(dead_code)] // each test file uses a different subset

use nalgebra::{Point3, Vector3};

type P = Point3<f64>;
type V = Vector3<f64>;

/// The generator's state.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    pub fn unit(&mut self) -> V {
        loop {
            let v = V::new(
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
                self.range(-1.0, 1.0),
            );
            let n = v.norm();
            if n > 0.1 && n <= 1.0 {
                return v / n;
            }
        }
    }
    /// Barycentric weights of a uniform random point of a triangle.
    pub fn barycentric(&mut self) -> [f64; 3] {
        let (u, v) = (self.next(), self.next());
        let (u, v) = if u + v > 1.0 {
            (1.0 - u, 1.0 - v)
        } else {
            (u, v)
        };
        [1.0 - u - v, u, v]
    }
}

/// Where the random configurations lie, m: half a metre from the origin of the scene.
pub const ORIGIN: [f64; 3] = [0.3, -0.2, 0.5];

/// A triangle with edges of 2 to 5 mm near (0.3, -0.2, 0.5) m.
pub fn random_triangle(rng: &mut Rng) -> [P; 3] {
    let centre = P::from(ORIGIN) + rng.unit() * rng.range(0.0, 0.01);
    loop {
        let tri = [0; 3].map(|_| centre + rng.unit() * rng.range(0.0, 0.003));
        let edges = [0, 1, 2].map(|i| (tri[(i + 1) % 3] - tri[i]).norm());
        let area = 0.5 * (tri[1] - tri[0]).cross(&(tri[2] - tri[0])).norm();
        let longest = edges.iter().cloned().fold(0.0, f64::max);
        if edges.iter().all(|&e| (0.002..=0.005).contains(&e)) && area > 0.2 * longest * longest {
            return tri;
        }
    }
}
