//! From an operator's compiled parameters (one [`Arg`] per registry
//! parameter, defaults filled in) to its typed [`OpArgs`]. Parameters are
//! read by key here, once, when the file is compiled; the engine reads
//! struct fields. A key or kind this file and the registry disagree on,
//! or a parameter no field takes, is a programming error that compiling
//! the operator's registry example finds (`tests/tooling.rs` does it for
//! every row).

use crate::rules::op_args::{
    ChoiceArg, ExtrudeArgs, GridKind, InsetArgs, MeshingArgs, OpArgs, SkinArgs, TessellateArgs,
};
use crate::rules::operators::{OpId, OperatorDef};
use crate::rules::program::{Arg, Scalar, Vector};

/// The parameters of one operator, taken by key.
struct Reader {
    def: &'static OperatorDef,
    args: Vec<Option<Arg>>,
}

impl Reader {
    fn take(&mut self, key: &str) -> Arg {
        let i = self
            .def
            .params
            .iter()
            .position(|p| p.key == key)
            .unwrap_or_else(|| panic!("registry: `{}` has no parameter `{key}`", self.def.name));
        self.args[i]
            .take()
            .unwrap_or_else(|| panic!("`{}.{key}` taken twice", self.def.name))
    }

    fn wrong(&self, key: &str, arg: &Arg, what: &str) -> ! {
        panic!("registry: `{}.{key}` is {arg:?}, not {what}", self.def.name)
    }

    fn opt_scalar(&mut self, key: &str) -> Option<Scalar> {
        match self.take(key) {
            Arg::Scalar(e) => Some(e),
            Arg::Absent => None,
            other => self.wrong(key, &other, "a scalar"),
        }
    }

    /// A scalar the registry defaults (or requires).
    fn scalar(&mut self, key: &str) -> Scalar {
        self.opt_scalar(key)
            .unwrap_or_else(|| panic!("registry: `{}.{key}` has no default", self.def.name))
    }

    fn opt_vector(&mut self, key: &str) -> Option<Vector> {
        match self.take(key) {
            Arg::Vector(v) => Some(v),
            Arg::Absent => None,
            other => self.wrong(key, &other, "a vector"),
        }
    }

    fn vector(&mut self, key: &str) -> Vector {
        self.opt_vector(key)
            .unwrap_or_else(|| panic!("registry: `{}.{key}` has no default", self.def.name))
    }

    fn opt_pair(&mut self, key: &str) -> Option<[Scalar; 2]> {
        match self.take(key) {
            Arg::Pair(p) => Some(p),
            Arg::Absent => None,
            other => self.wrong(key, &other, "a pair"),
        }
    }

    fn pair(&mut self, key: &str) -> [Scalar; 2] {
        self.opt_pair(key)
            .unwrap_or_else(|| panic!("registry: `{}.{key}` has no default", self.def.name))
    }

    fn opt_list(&mut self, key: &str) -> Option<Vec<Scalar>> {
        match self.take(key) {
            Arg::List(l) => Some(l),
            Arg::Absent => None,
            other => self.wrong(key, &other, "a list"),
        }
    }

    fn flag(&mut self, key: &str) -> bool {
        match self.take(key) {
            Arg::Bool(b) => b,
            other => self.wrong(key, &other, "a defaulted flag"),
        }
    }

    fn opt_choice<T: ChoiceArg>(&mut self, key: &str) -> Option<T> {
        match self.take(key) {
            Arg::Choice(i) => Some(T::from_index(i)),
            Arg::Absent => None,
            other => self.wrong(key, &other, "a choice"),
        }
    }

    fn choice<T: ChoiceArg>(&mut self, key: &str) -> T {
        self.opt_choice(key)
            .unwrap_or_else(|| panic!("registry: `{}.{key}` has no default", self.def.name))
    }

    fn resource(&mut self, key: &str) -> usize {
        match self.take(key) {
            Arg::Resource(i) => i,
            other => self.wrong(key, &other, "a required path"),
        }
    }

    fn tree(&mut self, key: &str) -> usize {
        match self.take(key) {
            Arg::Tree(i) => i,
            other => self.wrong(key, &other, "a required tree"),
        }
    }

    fn part(&mut self, key: &str) -> u32 {
        match self.take(key) {
            Arg::Part(i) => i,
            other => self.wrong(key, &other, "a required part"),
        }
    }

    fn surface(&mut self, key: &str) -> usize {
        match self.take(key) {
            Arg::Surface(i) => i,
            other => self.wrong(key, &other, "a required surface"),
        }
    }

    fn opt_bounds(&mut self, key: &str) -> Option<Box<[Vector; 2]>> {
        match self.take(key) {
            Arg::Bounds(b) => Some(b),
            Arg::Absent => None,
            other => self.wrong(key, &other, "a box"),
        }
    }

    fn has(&self, key: &str) -> bool {
        self.def.params.iter().any(|p| p.key == key)
    }

    fn extrude(&mut self) -> ExtrudeArgs {
        ExtrudeArgs {
            offset: self.opt_vector("offset"),
            distance: self.opt_scalar("distance"),
            keep_original: self.flag("keep_original"),
        }
    }

    fn inset(&mut self) -> InsetArgs {
        InsetArgs {
            thickness: self.scalar("thickness"),
            depth: self.scalar("depth"),
        }
    }

    /// The meshing keys; `skin` has no `cells`, `grid` or `padding`.
    fn meshing(&mut self) -> MeshingArgs {
        MeshingArgs {
            cell: self.opt_scalar("cell"),
            cells: if self.has("cells") {
                self.opt_scalar("cells")
            } else {
                None
            },
            mesher: self.choice("mesher"),
            vertex: self.choice("vertex"),
            grid: if self.has("grid") {
                self.choice("grid")
            } else {
                GridKind::LatticeHalf
            },
            padding: if self.has("padding") {
                self.opt_scalar("padding")
            } else {
                None
            },
            domain: self.opt_bounds("domain"),
        }
    }

    fn tessellate(&mut self) -> TessellateArgs {
        TessellateArgs {
            surface: self.surface("surface"),
            mode: self.choice("mode"),
            tolerance: self.opt_scalar("tolerance"),
            max_level: self.scalar("max_level"),
            test: self.choice("test"),
            threshold: self.opt_scalar("threshold"),
            combine: self.choice("combine"),
            cells: self.opt_pair("cells"),
            per_patch: self.flag("per_patch"),
        }
    }

    /// Every parameter has a field: one left over is a field forgotten.
    fn finish(self, args: OpArgs) -> OpArgs {
        if let Some(p) = self
            .def
            .params
            .iter()
            .zip(&self.args)
            .find(|(_, a)| a.is_some())
        {
            panic!(
                "registry: `{}.{}` has no field in OpArgs",
                self.def.name, p.0.key
            );
        }
        args
    }
}

/// `def`'s typed arguments from its compiled parameters (in the
/// registry's order). G³ commands are compiled elsewhere.
pub(super) fn typed(def: &'static OperatorDef, args: Vec<Arg>) -> OpArgs {
    let mut r = Reader {
        def,
        args: args.into_iter().map(Some).collect(),
    };
    let typed = match def.id {
        OpId::Vertex => OpArgs::Vertex {
            at: r.vector("at"),
            radius: r.opt_scalar("radius"),
        },
        OpId::Circle => OpArgs::Circle {
            segments: r.scalar("segments"),
            radius: r.scalar("radius"),
            fill: r.flag("fill"),
        },
        OpId::Grid => OpArgs::Grid {
            segments: r.pair("segments"),
            size: r.pair("size"),
        },
        OpId::Cube => OpArgs::Cube {
            size: r.scalar("size"),
        },
        OpId::UvSphere => OpArgs::UvSphere {
            segments: r.scalar("segments"),
            rings: r.scalar("rings"),
            radius: r.scalar("radius"),
        },
        OpId::Cylinder => OpArgs::Cylinder {
            segments: r.scalar("segments"),
            radius: r.scalar("radius"),
            radius_top: r.scalar("radius_top"),
            depth: r.scalar("depth"),
            caps: r.flag("caps"),
        },
        OpId::Cone => OpArgs::Cone {
            segments: r.scalar("segments"),
            radius: r.scalar("radius"),
            depth: r.scalar("depth"),
            caps: r.flag("caps"),
        },
        OpId::Import => OpArgs::Import {
            path: r.resource("path"),
            weld: r.opt_scalar("weld"),
            up: r.choice("up"),
        },
        OpId::Translate => OpArgs::Translate {
            offset: r.vector("offset"),
        },
        OpId::Rotate => OpArgs::Rotate {
            angle: r.scalar("angle"),
            axis: r.vector("axis"),
            center: r.vector("center"),
        },
        OpId::Scale => OpArgs::Scale {
            factor: r.vector("factor"),
            center: r.vector("center"),
        },
        OpId::ExtrudeVerts => OpArgs::ExtrudeVerts(r.extrude()),
        OpId::ExtrudeEdges => OpArgs::ExtrudeEdges(r.extrude()),
        OpId::ExtrudeFaces => OpArgs::ExtrudeFaces(r.extrude()),
        OpId::ExtrudeRegion => OpArgs::ExtrudeRegion(r.extrude()),
        OpId::InsetFaces => OpArgs::InsetFaces(r.inset()),
        OpId::InsetRegion => OpArgs::InsetRegion(r.inset()),
        OpId::SplitEdges => OpArgs::SplitEdges {
            cuts: r.opt_scalar("cuts"),
            ratios: r.opt_list("ratios"),
        },
        OpId::Triangulate => OpArgs::Triangulate,
        OpId::Subdivide => OpArgs::Subdivide {
            scheme: r.choice("scheme"),
            levels: r.scalar("levels"),
            boundary: r.choice("boundary"),
            crease_angle: r.opt_scalar("crease_angle"),
        },
        OpId::Crease => OpArgs::Crease {
            sharpness: r.scalar("sharpness"),
        },
        OpId::ConvexHull => OpArgs::ConvexHull {
            triangulate: r.flag("triangulate"),
        },
        OpId::Boolean => OpArgs::Boolean {
            operation: r.choice("operation"),
            with: r.part("with"),
        },
        OpId::Spin => OpArgs::Spin {
            angle: r.scalar("angle"),
            steps: r.scalar("steps"),
            axis: r.vector("axis"),
            center: r.vector("center"),
        },
        OpId::BridgeLoops => OpArgs::BridgeLoops {
            twist: r.scalar("twist"),
            segments: r.scalar("segments"),
        },
        OpId::Bevel => OpArgs::Bevel {
            width: r.scalar("width"),
            offset_type: r.choice("offset_type"),
            segments: r.scalar("segments"),
            profile: r.scalar("profile"),
            clamp_overlap: r.flag("clamp_overlap"),
        },
        OpId::Solidify => OpArgs::Solidify {
            thickness: r.scalar("thickness"),
            offset: r.scalar("offset"),
            even: r.flag("even"),
            rim: r.flag("rim"),
        },
        OpId::Assign => OpArgs::Assign,
        OpId::Reverse => OpArgs::Reverse,
        OpId::RecomputeNormals => OpArgs::RecomputeNormals {
            outside: r.flag("outside"),
        },
        OpId::Delete => OpArgs::Delete {
            mode: r.choice("mode"),
        },
        OpId::Duplicate => OpArgs::Duplicate,
        OpId::DissolveEdges => OpArgs::DissolveEdges,
        OpId::MakeFace => OpArgs::MakeFace,
        OpId::Merge => OpArgs::Merge {
            distance: r.scalar("distance"),
        },
        OpId::Mirror => OpArgs::Mirror {
            axis: r.opt_choice("axis"),
            normal: r.vector("normal"),
            point: r.vector("point"),
            merge_distance: r.scalar("merge_distance"),
        },
        OpId::RegionExtend => OpArgs::RegionExtend { by: r.choice("by") },
        OpId::RegionReduce => OpArgs::RegionReduce { by: r.choice("by") },
        OpId::Skin => OpArgs::Skin(Box::new(SkinArgs {
            sides: r.scalar("sides"),
            radius: r.scalar("radius"),
            joints: r.flag("joints"),
            keep_wires: r.flag("keep_wires"),
            method: r.choice("method"),
            blend: r.opt_scalar("blend"),
            min_radius: r.opt_scalar("min_radius"),
            meshing: r.meshing(),
        })),
        OpId::Sdf => OpArgs::Sdf {
            tree: r.tree("tree"),
            meshing: Box::new(r.meshing()),
        },
        OpId::SdfPart => OpArgs::SdfPart {
            tree: r.tree("tree"),
            relative: r.flag("relative"),
            meshing: Box::new(r.meshing()),
        },
        OpId::SdfBoolean => OpArgs::SdfBoolean {
            tree: r.tree("tree"),
            operation: r.choice("operation"),
            blend: r.scalar("blend"),
            meshing: Box::new(r.meshing()),
        },
        OpId::Nurbs => OpArgs::Nurbs(Box::new(r.tessellate())),
        OpId::NurbsPart => OpArgs::NurbsPart {
            tessellate: Box::new(r.tessellate()),
            relative: r.flag("relative"),
        },
        OpId::NurbsPatch => OpArgs::NurbsPatch {
            lift: r.scalar("lift"),
            cells: r.scalar("cells"),
        },
        OpId::PnSmooth => OpArgs::PnSmooth {
            level: r.scalar("level"),
            pattern: r.choice("pattern"),
            crease: r.scalar("crease"),
        },
        OpId::CreateEdge
        | OpId::SplitEdge
        | OpId::CreateFace
        | OpId::SplitFace
        | OpId::EditNode => unreachable!("G³ commands compile to a Command"),
    };
    r.finish(typed)
}
