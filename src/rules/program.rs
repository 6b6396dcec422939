//! The compiled program: what the engine runs, with every name resolved to
//! a slot and every expression compiled. Built by [`super::compile`]; the
//! engine never re-checks it.

use std::path::PathBuf;
use std::sync::Arc;

use crate::kernel::Domain;

use super::expr::Expr;
use super::operators::OperatorDef;
use super::sdf_tree::SdfForest;

/// A compiled rule file.
#[derive(Debug, Clone)]
pub struct Program {
    /// Display name of the rule file.
    pub file: String,
    /// Directory that relative paths in the file resolve against.
    pub base_dir: PathBuf,
    /// Seed used when the command line gives none.
    pub default_seed: u64,
    /// FNV-1a of the rule file's bytes (and overrides), for stats.
    pub rule_hash: u64,
    /// Parameter names by slot (sorted by name).
    pub param_names: Vec<String>,
    /// Parameters in evaluation order (dependencies first).
    pub params: Vec<Param>,
    /// The start step (if any) followed by the steps, in order, with rules
    /// included and repeats unrolled.
    pub steps: Vec<Step>,
    /// Compound commands, referenced by index from [`Op::Compound`].
    pub compounds: Vec<Compound>,
    /// Number of steps in the whole program, compounds' contents included:
    /// every [`Step::uid`] is below it.
    pub step_count: usize,
    /// Whether any step is a G³ command or compound, so the engine keeps
    /// node radius, frames and ages.
    pub uses_graph: bool,
    /// The file's default policy for G³ commands.
    pub policy: Policy,
    /// The file's default reaction to an intersecting product.
    pub on_intersection: OnIntersection,
    /// Whether any step may cancel a compound or a rule application, so
    /// the engine keeps snapshots to roll back to.
    pub may_cancel: bool,
    /// Whether anything draws per primitive (`random` in an expression,
    /// a command's `probability` or `vary_*`): the engine then keeps each
    /// primitive's lineage key, which those draws are keyed by.
    pub draws_per_primitive: bool,
    /// Every file the program needs, each once, in first-use order: the
    /// caller reads them before the run (the engine does no I/O) and hands
    /// them over by index ([`Op::Import`]'s `resource`).
    pub resources: Vec<Resource>,
    /// Every signed distance tree, referenced by node index from
    /// [`Arg::Tree`].
    pub sdf: SdfForest,
    /// Every `[nurbs.NAME]` surface, in file order, referenced by index
    /// from [`Arg::Surface`].
    pub nurbs: Vec<crate::rules::nurbs_def::SurfaceDef>,
    /// Parts and materials (issue 16); part 0 is the default part.
    pub look: Look,
    /// Whether any step names a part or material, so the engine keeps
    /// the face layers [`PART_LAYER`] and [`MATERIAL_LAYER`].
    pub tags_looks: bool,
}

/// Face (and wire edge) layer holding each element's part index.
pub const PART_LAYER: &str = "part";
/// Face layer holding each face's colour (linear RGB), when a part has a
/// colour expression.
pub const COLOR_LAYER: &str = "color";
/// Face layer holding each face's material index, or [`NO_MATERIAL`].
pub const MATERIAL_LAYER: &str = "material";
/// A face whose step named no material: its part's applies.
pub const NO_MATERIAL: i32 = -1;

/// How the model looks in its files: its parts and materials.
#[derive(Debug, Clone, Default)]
pub struct Look {
    /// Part 0 is the default part (named after the rule file), then the
    /// `[parts.NAME]` tables in name order, then parts only steps name,
    /// in the order the compiler meets them.
    pub parts: Vec<PartLook>,
    /// The `[materials.NAME]` tables, in name order.
    pub materials: Vec<crate::geom::Material>,
    /// Colour expressions, referenced by [`PartLook::color`].
    pub colors: Vec<ColorSpec>,
}

/// A face colour computed when the run ends (`color = { hsv = [h, s, v] }`
/// or `{ rgb = [r, g, b] }`): three expressions over the face's properties
/// and the parameters, each clamped into [0, 1] (hue wraps), sRGB.
#[derive(Debug, Clone)]
pub struct ColorSpec {
    pub hsv: bool,
    pub channels: [Condition; 3],
}

/// One part's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct PartLook {
    pub name: String,
    /// Index into [`Look::materials`]; `None`: graftal's fallback.
    pub material: Option<u32>,
    /// Crease angle of the smooth normals in degrees; 0 = flat.
    pub crease: f64,
    pub uv: Option<crate::geom::uv::UvMapping>,
    /// Index into [`Look::colors`].
    pub color: Option<u32>,
}

impl Look {
    /// The index of part `name`, added with part 0's settings when new.
    pub fn part_index(&mut self, name: &str) -> u32 {
        if let Some(i) = self.parts.iter().position(|p| p.name == name) {
            return i as u32;
        }
        let mut part = self.parts.first().cloned().unwrap_or(PartLook {
            name: String::new(),
            material: None,
            crease: 0.0,
            uv: None,
            color: None,
        });
        part.name = name.to_owned();
        self.parts.push(part);
        self.parts.len() as u32 - 1
    }
}

/// A file a rule file refers to.
#[derive(Debug, Clone, PartialEq)]
pub struct Resource {
    /// Resolved against the rule file's directory.
    pub path: PathBuf,
    /// The path as written.
    pub written: String,
    /// `file:line:column` of the path, for errors about the file.
    pub location: String,
    /// What the file holds.
    pub kind: ResourceKind,
}

/// How a resource file is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ResourceKind {
    /// A mesh (`import`, `sdf` meshes): format by extension.
    Mesh,
    /// NURBS patches (`[nurbs.NAME] patches = "…"`): `.bpt` or OBJ free-form.
    Patches,
}

/// What happens when a product of a command under `policy = "intersect"`
/// would intersect the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OnIntersection {
    /// That application is not made (counted in the stats).
    Skip,
    /// The whole application of the innermost compound is rolled back.
    CancelCompound,
    /// The whole application of the innermost rule is rolled back.
    CancelRule,
    /// The run fails.
    Error,
}

/// What a G³ command does about primitives that coincide with the model
/// (thesis 003 §3.1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Policy {
    /// Products are added as they are.
    None,
    /// Nodes the command made or moved are merged with the nodes within
    /// `tolerance`, and the topology repaired.
    Merge { tolerance: f64 },
    /// Each application's would-be products are tested against the model
    /// first; intersecting ones are handled by `on_intersection`.
    Intersect,
}

/// A compound command (thesis 003 §3.3): run its steps inside a scope made
/// of one initial primitive, its sub-primitives and what the steps create.
#[derive(Debug, Clone)]
pub struct Compound {
    pub name: String,
    /// Kind of the initial primitive.
    pub domain: Domain,
    /// Condition from the definition; the calling step's `select` is added.
    pub select: Option<Condition>,
    pub steps: Vec<Step>,
}

/// A compound's own parameters (Table 3.2), evaluated per initial primitive.
#[derive(Debug, Clone)]
pub struct FrameParams {
    /// Relative to the initial primitive instead of the enclosing reference.
    pub relative: bool,
    pub length: Option<Condition>,
    pub radius: Option<Condition>,
    pub heading: Option<Box<[Condition; 3]>>,
    pub up: Option<Box<[Condition; 3]>>,
}

/// The five G³ commands (thesis 003 §2.4.5, §3.4).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CommandKind {
    CreateEdge,
    SplitEdge,
    CreateFace,
    SplitFace,
    EditNode,
}

/// A G³ command's parameters: conditions (expressions over parameters and
/// the matched primitive's properties), evaluated per primitive on the
/// generation the command reads.
#[derive(Debug, Clone)]
pub struct Command {
    pub kind: CommandKind,
    pub relative: bool,
    pub length: Option<Condition>,
    pub radius: Option<Condition>,
    pub heading: Option<Box<[Condition; 3]>>,
    pub up: Option<Box<[Condition; 3]>>,
    /// Fixed rotations in degrees: about U, L, H.
    pub turn: Option<Condition>,
    pub pitch: Option<Condition>,
    pub roll: Option<Condition>,
    pub vary_length: Option<Condition>,
    pub vary_radius: Option<Condition>,
    pub vary_turn: Option<Condition>,
    pub vary_pitch: Option<Condition>,
    pub vary_roll: Option<Condition>,
    pub probability: Option<Condition>,
    /// `split_face`: which of the face's nodes to connect (vertex condition).
    pub nodes: Option<Condition>,
}

impl Command {
    /// Whether the command draws random values per primitive.
    pub fn draws(&self) -> bool {
        self.probability.is_some()
            || [
                &self.vary_length,
                &self.vary_radius,
                &self.vary_turn,
                &self.vary_pitch,
                &self.vary_roll,
            ]
            .iter()
            .any(|v| v.is_some())
    }
}

#[derive(Debug, Clone)]
pub struct Param {
    pub name: String,
    pub slot: u32,
    /// Random stream key (`param/NAME`).
    pub key: u64,
    pub kind: ParamKind,
    pub clamp: Option<(Expr, Expr)>,
}

#[derive(Debug, Clone)]
pub enum ParamKind {
    Expr(Expr),
    Uniform {
        low: Expr,
        high: Expr,
    },
    Normal {
        mean: Expr,
        sd: Expr,
    },
    Int {
        low: Expr,
        high: Expr,
    },
    Choice {
        values: Vec<Expr>,
        weights: Vec<f64>,
    },
}

/// A compiled expression over parameters: evaluated once per step.
pub type Scalar = Expr;

#[derive(Debug, Clone)]
pub struct Vector(pub [Scalar; 3]);

/// A property of an element that conditions can read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Property {
    Id,
    Random,
    Position(usize),
    Center(usize),
    Normal(usize),
    Min(usize),
    Max(usize),
    Direction(usize),
    /// Edge: position of the pre-node / post-node.
    PrePosition(usize),
    PostPosition(usize),
    /// Position (node), centre (edge, face) in the scope's frame: x and y
    /// span [0, 1] over the initial face, z is measured in its size.
    Relative(usize),
    /// Length / area over the initial primitive's size / area.
    RelativeLength,
    RelativeArea,
    /// Generation that created the primitive.
    Age,
    /// The generation of the command being run (same for every primitive).
    Generation,
    Radius,
    /// Node: edges leaving / entering it. Edge: edges leaving its post-node
    /// / entering its pre-node.
    OutEdges,
    InEdges,
    /// Edge: other edges sharing a node with it.
    EdgeNeighborEdges,
    /// Node: mean length of its incoming edges (0 if none); edge: its length.
    PreLength,
    Length,
    Area,
    Sides,
    Degree,
    FaceCount,
    EdgeNeighbors,
    VertNeighbors,
}

/// A per-element condition: an expression whose slots are the parameters
/// followed by the element properties (slot `param_count + k` is the
/// property numbered k by `compile::property_index`).
#[derive(Debug, Clone)]
pub struct Condition {
    pub expr: Expr,
}

/// One step of the program, as it runs: its place (uid, path), what it
/// reads, and its compiled body. Copies of one written step (`repeat`, a
/// rule included several times) share the body, so a program costs a few
/// dozen bytes per unrolled step, not a compiled operator each.
#[derive(Debug, Clone)]
pub struct Step {
    /// Unique over the program (compound contents included), in program
    /// order; the step's generation number is `uid + 1`.
    pub uid: u32,
    /// Full path: rule and compound names, repeat counts, the step's name
    /// (shared with the run's statistics, not copied per run).
    pub name: std::sync::Arc<str>,
    /// Random stream key: `step/` and the step's key path, whose last part
    /// is its name or, unnamed, a hash of its content (`compile::step_key`).
    pub key: u64,
    /// Uids of the earlier step whose created elements are the candidates
    /// (every copy of a repeated step).
    pub from: Option<Vec<u32>>,
    /// The step's own reaction to intersections; `None` inherits.
    pub on_intersection: Option<OnIntersection>,
    /// The rule applications the step belongs to, outermost first: one
    /// number per include (and per repeat of it), unique in the program.
    pub rule_instances: Vec<u32>,
    pub body: Arc<StepBody>,
}

/// What a written step does, compiled once for all its copies.
#[derive(Debug)]
pub struct StepBody {
    /// `file:line:column` of the step's operator, for runtime errors.
    pub location: String,
    /// Element kind the step selects.
    pub domain: Domain,
    pub select: Option<Condition>,
    pub op: Op,
    /// The step's own policy (G³ commands and compounds); `None` inherits
    /// the enclosing compound call's, or the file's.
    pub policy: Option<Policy>,
    /// Part the products belong to (index into [`Look::parts`]).
    pub part: Option<u32>,
    /// Material of the products (index into [`Look::materials`]).
    pub material: Option<u32>,
}

impl std::ops::Deref for Step {
    type Target = StepBody;
    fn deref(&self) -> &StepBody {
        &self.body
    }
}

/// A step's operator, by family.
#[derive(Debug, Clone)]
pub enum Op {
    /// A create, kernel or whole-mesh operator ([`Family::Create`],
    /// [`Family::Kernel`], [`Family::WholeMesh`]): its definition and its
    /// compiled arguments.
    Call(Box<Call>),
    /// A G³ command.
    Command(Box<Command>),
    /// A compound command call.
    Compound {
        index: usize,
        frame: Box<FrameParams>,
    },
}

impl Op {
    /// The operator's name as written in rule files.
    pub fn name(&self) -> &'static str {
        match self {
            Op::Call(call) => call.def.name,
            Op::Command(c) => match c.kind {
                CommandKind::CreateEdge => "create_edge",
                CommandKind::SplitEdge => "split_edge",
                CommandKind::CreateFace => "create_face",
                CommandKind::SplitFace => "split_face",
                CommandKind::EditNode => "edit_node",
            },
            Op::Compound { .. } => "compound",
        }
    }

    /// Whether the operator makes geometry from nothing (no selection).
    pub fn is_create(&self) -> bool {
        matches!(self, Op::Call(call) if call.def.is_create())
    }
}

/// A create, kernel or whole-mesh operator with its typed arguments
/// (compiled against its registry row, defaults filled in).
#[derive(Debug, Clone)]
pub struct Call {
    pub def: &'static OperatorDef,
    pub args: super::op_args::OpArgs,
}

/// A compiled argument.
#[derive(Debug, Clone)]
pub enum Arg {
    /// Not written and without a default.
    Absent,
    Scalar(Scalar),
    Vector(Vector),
    Pair([Scalar; 2]),
    List(Vec<Scalar>),
    Bool(bool),
    /// The index of the name among the parameter's choices.
    Choice(usize),
    /// The index of the file in [`Program::resources`].
    Resource(usize),
    /// The root node of a tree in [`Program::sdf`].
    Tree(usize),
    /// A box: lowest corner, highest corner.
    Bounds(Box<[Vector; 2]>),
    /// The index of a surface in [`Program::nurbs`].
    Surface(usize),
    /// The index of a part in [`Look::parts`].
    Part(u32),
}
