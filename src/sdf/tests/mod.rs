//! Tests of the SDF pillar (moved with the folder into graftal).

mod fields;
mod hostile;
mod meshers;
mod meshfield;
mod skin;
mod table;

use glam::DVec3;

use crate::sdf::tape::Tape;
use crate::sdf::tree::{Node, NodeId, Tree, TreeLimits};

/// SplitMix64: a tiny portable generator for test data.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.f()
    }
    pub fn vec(&mut self, a: f64, b: f64) -> DVec3 {
        DVec3::new(self.range(a, b), self.range(a, b), self.range(a, b))
    }
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }
}

/// Compiles with default limits.
pub fn compile(t: &Tree, root: NodeId) -> Tape {
    Tape::compile(t, root, &TreeLimits::default()).expect("compile")
}

/// f at one point of a one-node-rooted tree.
pub fn eval(t: &Tree, root: NodeId, p: DVec3) -> f64 {
    compile(t, root).evaluator().eval(p)
}

/// Sphere r = 1 minus the box [0, 1]³: the peers' workload.
pub fn sphere_minus_box() -> Tape {
    let mut t = Tree::new();
    let ball = t.push(Node::Sphere { radius: 1.0 });
    let cube = t.push(Node::Box { size: DVec3::ONE });
    let cube = t.push(Node::Translate {
        child: cube,
        offset: DVec3::splat(0.5),
    });
    let root = t.push(Node::Difference {
        base: ball,
        subtract: vec![cube],
    });
    compile(&t, root)
}
