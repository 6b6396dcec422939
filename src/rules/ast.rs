//! The rule file as written: a spanned syntax tree deserialized from TOML or
//! RON with one schema. Nothing is resolved here; [`super::compile`] turns
//! it into a [`super::program::Program`] and reports semantic errors.
//!
//! Shape (TOML; RON mirrors it with `( key: value )` structs):
//! ```toml
//! seed = 7                       # default seed, `--seed` overrides
//! [params]                       # constants, expressions, distributions
//! width = { uniform = [0.4, 0.6] }
//! [start]                        # one create operator
//! grid = { segments = [3, 3], size = ["width", 1.0] }
//! [[step]]                       # operators in order
//! name = "legs"
//! select = "normal.z < -0.5"     # condition over element properties
//! extrude_faces = { distance = 0.5 }
//! ```
//! Enums are externally tagged (the operator name is the key), which keeps
//! exact source spans in TOML errors.

use std::fmt;

use serde::de::{self, Deserializer, MapAccess, SeqAccess, Visitor};
use serde::Deserialize;

use super::spanned::Spanned;

/// The whole file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RuleFile {
    #[serde(default)]
    pub seed: Option<Spanned<u64>>,
    #[serde(default)]
    pub params: Params,
    #[serde(default)]
    pub start: Option<Step>,
    #[serde(default, rename = "step", alias = "steps")]
    pub steps: Vec<Step>,
    /// Named command sequences (`[rules.NAME]`), included by `rule = "NAME"`.
    #[serde(default)]
    pub rules: Named<RuleDef>,
    /// Compound commands (`[compound.NAME]`), applied by `compound = "NAME"`.
    #[serde(default)]
    pub compound: Named<CompoundDef>,
    /// Signed distance trees (`[sdf.NAME]`: a table with a `kind`), used by
    /// the `sdf` operators' `tree` and by other trees' children.
    #[serde(default)]
    pub sdf: Named<Spanned<Args>>,
    /// Parametric surfaces (`[nurbs.NAME]`), used by the `nurbs` operator.
    #[serde(default)]
    pub nurbs: Named<Spanned<Args>>,
    /// Default policy of G³ commands about coinciding primitives.
    #[serde(default)]
    pub policy: Option<Spanned<PolicyName>>,
    /// Default merge tolerance (model units).
    #[serde(default)]
    pub tolerance: Option<Spanned<f64>>,
    /// Default reaction to an intersecting product (`policy = "intersect"`).
    #[serde(default)]
    pub on_intersection: Option<Spanned<OnIntersectionName>>,
    /// Materials (`[materials.NAME]`), named by parts and steps.
    #[serde(default)]
    pub materials: Named<Spanned<Args>>,
    /// Part settings (`[parts.NAME]`: material, normals, uv); parts named
    /// only by steps take the file's settings.
    #[serde(default)]
    pub parts: Named<Spanned<Args>>,
    /// The material of everything no part or step gives one.
    #[serde(default)]
    pub material: Option<Spanned<String>>,
    /// Shading normals of every part that sets none: `"flat"`, `"smooth"`
    /// or `{ crease = DEGREES }`.
    #[serde(default)]
    pub normals: Option<Spanned<ArgValue>>,
    /// Texture coordinates of every part that sets none: `"none"` or
    /// `{ projection = "box", size = 1 }`.
    #[serde(default)]
    pub uv: Option<Spanned<ArgValue>>,
    /// Face colours of every part that sets none: `{ hsv = [h, s, v] }`
    /// or `{ rgb = [r, g, b] }` over face properties.
    #[serde(default)]
    pub color: Option<Spanned<ArgValue>>,
}

/// What happens when a product would intersect the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OnIntersectionName {
    Skip,
    CancelCompound,
    CancelRule,
    Error,
}

/// What a G³ command does about primitives that coincide with the model
/// (thesis 003 §3.1–3.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PolicyName {
    None,
    Merge,
    Intersect,
}

/// A table of named definitions, in file order.
#[derive(Debug)]
pub struct Named<T>(pub Vec<(Spanned<String>, T)>);

impl<T> Default for Named<T> {
    fn default() -> Self {
        Named(Vec::new())
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Named<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct NamedVisitor<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for NamedVisitor<T> {
            type Value = Named<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table of named definitions")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Named<T>, A::Error> {
                let mut out = Vec::new();
                while let Some(key) = map.next_key::<Spanned<String>>()? {
                    out.push((key, map.next_value()?));
                }
                Ok(Named(out))
            }
        }
        // RON writes these as a struct: `rules: (grow: (step: [...]))`.
        d.deserialize_struct("Named", &[], NamedVisitor(std::marker::PhantomData))
    }
}

/// `[rules.NAME]`: a named list of steps.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RuleDef {
    #[serde(default, rename = "step", alias = "steps")]
    pub steps: Vec<Step>,
}

/// `[compound.NAME]`: a compound command (thesis 003 §3.3).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompoundDef {
    /// Kind of the initial primitive.
    pub on: Spanned<DomainName>,
    /// Condition that selects initial primitives.
    pub select: Option<Spanned<String>>,
    /// The reference frame and sizes the contained commands build on.
    pub relative: Option<Spanned<bool>>,
    pub length: Option<Value>,
    pub radius: Option<Value>,
    pub heading: Option<Vector>,
    pub up: Option<Vector>,
    #[serde(default, rename = "step", alias = "steps")]
    pub steps: Vec<Step>,
}

impl CompoundDef {
    pub fn frame(&self) -> FrameSpec {
        FrameSpec {
            relative: self.relative.clone(),
            length: self.length.clone(),
            radius: self.radius.clone(),
            heading: self.heading.clone(),
            up: self.up.clone(),
        }
    }
}

/// A compound command's own parameters (Table 3.2): absolute, or relative
/// to its initial primitive.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FrameSpec {
    pub relative: Option<Spanned<bool>>,
    pub length: Option<Value>,
    pub radius: Option<Value>,
    pub heading: Option<Vector>,
    pub up: Option<Vector>,
}

/// `compound = "NAME"` or `compound = { name = "NAME", length = 2, … }`.
#[derive(Debug, Clone, PartialEq)]
pub struct CompoundCall {
    pub name: Spanned<String>,
    pub frame: FrameSpec,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CompoundCallTable {
    name: Spanned<String>,
    relative: Option<Spanned<bool>>,
    length: Option<Value>,
    radius: Option<Value>,
    heading: Option<Vector>,
    up: Option<Vector>,
}

impl<'de> Deserialize<'de> for CompoundCall {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct CallVisitor;
        impl<'de> Visitor<'de> for CallVisitor {
            type Value = CompoundCall;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str(
                    "a compound name, or a table { name = \"NAME\", length = …, heading = […] }",
                )
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<CompoundCall, E> {
                Ok(CompoundCall {
                    name: Spanned::new(v.to_owned()),
                    frame: FrameSpec::default(),
                })
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<CompoundCall, A::Error> {
                let t = CompoundCallTable::deserialize(de::value::MapAccessDeserializer::new(map))?;
                Ok(CompoundCall {
                    name: t.name,
                    frame: FrameSpec {
                        relative: t.relative,
                        length: t.length,
                        radius: t.radius,
                        heading: t.heading,
                        up: t.up,
                    },
                })
            }
        }
        d.deserialize_any(CallVisitor)
    }
}

/// A number or an expression string.
#[derive(Debug, Clone, PartialEq)]
pub enum Scalar {
    Number(f64),
    Expr(String),
}

pub type Value = Spanned<Scalar>;

impl<'de> Deserialize<'de> for Scalar {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct ScalarVisitor;
        impl Visitor<'_> for ScalarVisitor {
            type Value = Scalar;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number or an expression string")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Scalar, E> {
                Ok(Scalar::Number(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Scalar, E> {
                Ok(Scalar::Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Scalar, E> {
                Ok(Scalar::Number(v as f64))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Scalar, E> {
                Ok(Scalar::Expr(v.to_owned()))
            }
        }
        d.deserialize_any(ScalarVisitor)
    }
}

/// A 3-vector: `[x, y, z]` of scalars, or one scalar used for all three.
#[derive(Debug, Clone, PartialEq)]
pub enum VectorSpec {
    Components(Box<[Value; 3]>),
    Uniform(Scalar),
}

pub type Vector = Spanned<VectorSpec>;

impl<'de> Deserialize<'de> for VectorSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct VectorVisitor;
        impl<'de> Visitor<'de> for VectorVisitor {
            type Value = VectorSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a 3-vector [x, y, z] or a single number or expression")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<VectorSpec, E> {
                Ok(VectorSpec::Uniform(Scalar::Number(v)))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<VectorSpec, E> {
                Ok(VectorSpec::Uniform(Scalar::Number(v as f64)))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<VectorSpec, E> {
                Ok(VectorSpec::Uniform(Scalar::Number(v as f64)))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<VectorSpec, E> {
                Ok(VectorSpec::Uniform(Scalar::Expr(v.to_owned())))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<VectorSpec, A::Error> {
                let mut items = Vec::with_capacity(3);
                while let Some(item) = seq.next_element::<Value>()? {
                    items.push(item);
                }
                let n = items.len();
                let array: [Value; 3] = items
                    .try_into()
                    .map_err(|_| de::Error::invalid_length(n, &"3 components"))?;
                Ok(VectorSpec::Components(Box::new(array)))
            }
        }
        d.deserialize_any(VectorVisitor)
    }
}

/// Two scalars written as a list, `[a, b]`, in TOML and RON alike (a
/// fixed-size array would be a tuple, `(a, b)`, in RON).
#[derive(Debug, Clone, PartialEq)]
pub struct Pair(pub [Value; 2]);

impl<'de> Deserialize<'de> for Pair {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct PairVisitor;
        impl<'de> Visitor<'de> for PairVisitor {
            type Value = Pair;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a list of two numbers or expressions, [a, b]")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Pair, A::Error> {
                let mut items = Vec::with_capacity(2);
                while let Some(item) = seq.next_element::<Value>()? {
                    items.push(item);
                }
                let n = items.len();
                let pair: [Value; 2] = items
                    .try_into()
                    .map_err(|_| de::Error::invalid_length(n, &"2 values"))?;
                Ok(Pair(pair))
            }
        }
        d.deserialize_seq(PairVisitor)
    }
}

/// Parameters in file order.
#[derive(Debug, Default)]
pub struct Params(pub Vec<(Spanned<String>, Spanned<ParamSpec>)>);

impl<'de> Deserialize<'de> for Params {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct ParamsVisitor;
        impl<'de> Visitor<'de> for ParamsVisitor {
            type Value = Params;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table of parameters")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Params, A::Error> {
                let mut out = Vec::new();
                while let Some(key) = map.next_key::<Spanned<String>>()? {
                    out.push((key, map.next_value()?));
                }
                Ok(Params(out))
            }
        }
        // RON writes parameters as a struct: `params: (width: 1.0)`.
        d.deserialize_struct("Params", &[], ParamsVisitor)
    }
}

/// One parameter: a constant, an expression over other parameters, or a
/// distribution the seed draws from.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamSpec {
    Number(f64),
    Expr(String),
    Table(Box<ParamTable>),
}

#[derive(Debug, Clone, PartialEq, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamTable {
    /// Uniform real in `[low, high)`.
    pub uniform: Option<Pair>,
    /// Normal `[mean, standard deviation]`.
    pub normal: Option<Pair>,
    /// Uniform integer in `[low, high]` (inclusive).
    pub int: Option<Pair>,
    /// One of these values, with optional `weights`.
    pub choice: Option<Vec<Value>>,
    pub weights: Option<Vec<Spanned<f64>>>,
    /// Clamp the drawn value into `[min, max]`.
    pub clamp: Option<Pair>,
}

impl<'de> Deserialize<'de> for ParamSpec {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct ParamVisitor;
        impl<'de> Visitor<'de> for ParamVisitor {
            type Value = ParamSpec;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, an expression string, or a distribution table such as { uniform = [0, 1] }")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<ParamSpec, E> {
                Ok(ParamSpec::Number(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<ParamSpec, E> {
                Ok(ParamSpec::Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<ParamSpec, E> {
                Ok(ParamSpec::Number(v as f64))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<ParamSpec, E> {
                Ok(ParamSpec::Expr(v.to_owned()))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<ParamSpec, A::Error> {
                ParamTable::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(|t| ParamSpec::Table(Box::new(t)))
            }
        }
        d.deserialize_any(ParamVisitor)
    }
}

/// Which elements a step's selection is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DomainName {
    /// `"verts"`, or `"vertices"` in full.
    #[serde(alias = "vertices")]
    Verts,
    Edges,
    Faces,
}

/// One step: an operator, and which elements it applies to.
#[derive(Debug, Clone)]
pub struct Step {
    /// Where the step is written (its table), for errors about the step as a whole.
    pub span: Option<std::ops::Range<usize>>,
    pub name: Option<Spanned<String>>,
    /// Condition over element properties; only matching elements are used.
    pub select: Option<Spanned<String>>,
    /// Start from what an earlier step created instead of the whole mesh.
    pub from: Option<Spanned<String>>,
    /// Element kind to select, when the operator accepts several.
    pub on: Option<Spanned<DomainName>>,
    /// The operator's key and arguments (`None` when the step names none).
    pub op: Option<(Spanned<String>, Spanned<Args>)>,
    /// Include a named rule's steps here instead of an operator.
    pub rule: Option<Spanned<String>>,
    /// Apply a compound command instead of an operator.
    pub compound: Option<(Spanned<String>, Spanned<CompoundCall>)>,
    /// Run the step (or the included rule) this many times in a row.
    pub repeat: Option<Spanned<i64>>,
    /// Policy about coinciding primitives (G³ commands and compounds).
    pub policy: Option<Spanned<PolicyName>>,
    /// Merge tolerance for this step.
    pub tolerance: Option<Spanned<f64>>,
    /// Reaction to an intersecting product.
    pub on_intersection: Option<Spanned<OnIntersectionName>>,
    /// The part the step's products belong to (inside a compound call:
    /// every product of the call whose step names none).
    pub part: Option<Spanned<String>>,
    /// The material of the step's products, over their part's.
    pub material: Option<Spanned<String>>,
    /// Keys that are neither step fields nor operators, and operators past
    /// the first: reported by the compiler at their exact position.
    pub stray_keys: Vec<Spanned<String>>,
}

/// The keys a step may hold besides its operator.
pub const STEP_KEYS: &[&str] = &[
    "name",
    "select",
    "from",
    "on",
    "rule",
    "compound",
    "repeat",
    "policy",
    "tolerance",
    "on_intersection",
    "part",
    "material",
];

/// An operator's arguments as written: its table's keys and values in
/// file order. What each key may hold is the registry's business
/// ([`super::operators`]); the compiler checks them against it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Args(pub Vec<(Spanned<String>, Spanned<ArgValue>)>);

impl Args {
    /// The entry for `key`, if written.
    pub fn get(&self, key: &str) -> Option<&(Spanned<String>, Spanned<ArgValue>)> {
        self.0.iter().find(|(k, _)| k.value == key)
    }
}

/// One value of an operator's table.
#[derive(Debug, Clone, PartialEq)]
pub enum ArgValue {
    Number(f64),
    /// A string: an expression, a name or a path, by the parameter's kind.
    Text(String),
    Bool(bool),
    /// A bare name (RON writes choices as `faces`, TOML as `"faces"`).
    Name(String),
    List(Vec<Spanned<ArgValue>>),
    Table(Args),
}

impl ArgValue {
    /// What the value is, for messages.
    pub fn describe(&self) -> &'static str {
        match self {
            ArgValue::Number(_) => "a number",
            ArgValue::Text(_) => "a string",
            ArgValue::Bool(_) => "a boolean",
            ArgValue::Name(_) => "a name",
            ArgValue::List(_) => "a list",
            ArgValue::Table(_) => "a table",
        }
    }
}

impl<'de> Deserialize<'de> for Args {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct ArgsVisitor;
        impl<'de> Visitor<'de> for ArgsVisitor {
            type Value = Args;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table of the operator's parameters, such as { size = 2 }")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Args, A::Error> {
                let mut out = Vec::new();
                while let Some(key) = map.next_key::<Spanned<String>>()? {
                    out.push((key, map.next_value()?));
                }
                Ok(Args(out))
            }
            fn visit_unit<E: de::Error>(self) -> Result<Args, E> {
                Ok(Args::default())
            }
        }
        // A struct to RON (`(size: 2)`, `()`), a table to TOML.
        d.deserialize_struct("Args", &[], ArgsVisitor)
    }
}

impl<'de> Deserialize<'de> for ArgValue {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct ValueVisitor;
        impl<'de> Visitor<'de> for ValueVisitor {
            type Value = ArgValue;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a number, a string, a boolean, a list or a table")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<ArgValue, E> {
                Ok(ArgValue::Number(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<ArgValue, E> {
                Ok(ArgValue::Number(v as f64))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<ArgValue, E> {
                Ok(ArgValue::Number(v as f64))
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<ArgValue, E> {
                Ok(ArgValue::Text(v.to_owned()))
            }
            fn visit_bool<E: de::Error>(self, v: bool) -> Result<ArgValue, E> {
                Ok(ArgValue::Bool(v))
            }
            fn visit_unit<E: de::Error>(self) -> Result<ArgValue, E> {
                Ok(ArgValue::Table(Args::default()))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<ArgValue, A::Error> {
                let mut items = Vec::new();
                while let Some(item) = seq.next_element::<Spanned<ArgValue>>()? {
                    items.push(item);
                }
                Ok(ArgValue::List(items))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<ArgValue, A::Error> {
                Args::deserialize(de::value::MapAccessDeserializer::new(map)).map(ArgValue::Table)
            }
            fn visit_enum<A: de::EnumAccess<'de>>(self, data: A) -> Result<ArgValue, A::Error> {
                use de::VariantAccess;
                let (name, variant) = data.variant::<String>()?;
                variant.unit_variant()?;
                Ok(ArgValue::Name(name))
            }
        }
        d.deserialize_any(ValueVisitor)
    }
}

impl<'de> Deserialize<'de> for Step {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let spanned = Spanned::<UnspannedStep>::deserialize(d)?;
        let mut step = spanned.value.0;
        step.span = spanned.span;
        Ok(step)
    }
}

/// A step before its own span is attached.
struct UnspannedStep(Step);

impl<'de> Deserialize<'de> for UnspannedStep {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct StepVisitor;
        impl<'de> Visitor<'de> for StepVisitor {
            type Value = UnspannedStep;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a step table with one operator key, such as { cube = { size = 2 } }")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<UnspannedStep, A::Error> {
                let mut step = Step {
                    span: None,
                    name: None,
                    select: None,
                    from: None,
                    on: None,
                    op: None,
                    rule: None,
                    compound: None,
                    repeat: None,
                    policy: None,
                    tolerance: None,
                    on_intersection: None,
                    part: None,
                    material: None,
                    stray_keys: Vec::new(),
                };
                while let Some(key) = map.next_key::<Spanned<String>>()? {
                    match key.value.as_str() {
                        "name" => step.name = Some(map.next_value()?),
                        "select" => step.select = Some(map.next_value()?),
                        "from" => step.from = Some(map.next_value()?),
                        "on" => step.on = Some(map.next_value()?),
                        "rule" => step.rule = Some(map.next_value()?),
                        "repeat" => step.repeat = Some(map.next_value()?),
                        "policy" => step.policy = Some(map.next_value()?),
                        "tolerance" => step.tolerance = Some(map.next_value()?),
                        "on_intersection" => step.on_intersection = Some(map.next_value()?),
                        "part" => step.part = Some(map.next_value()?),
                        "material" => step.material = Some(map.next_value()?),
                        "compound" => step.compound = Some((key, map.next_value()?)),
                        other => match next_operation(&mut map, other)? {
                            Some(operation) if step.op.is_none() => {
                                step.op = Some((key, operation))
                            }
                            _ => step.stray_keys.push(key),
                        },
                    }
                }
                Ok(UnspannedStep(step))
            }
        }
        // A struct to RON (`(name: "x", cube: ())`), a table to TOML.
        d.deserialize_struct("Step", step_fields(), StepVisitor)
    }
}

/// Reads the value of operator key `key`; `None` (value skipped) when `key`
/// names no operator.
fn next_operation<'de, A: MapAccess<'de>>(
    map: &mut A,
    key: &str,
) -> Result<Option<Spanned<Args>>, A::Error> {
    if super::operators::find(key).is_none() {
        map.next_value::<de::IgnoredAny>()?;
        return Ok(None);
    }
    map.next_value().map(Some)
}

/// Every key a step may hold, for `deserialize_struct` (RON needs the list).
fn step_fields() -> &'static [&'static str] {
    use std::sync::OnceLock;
    static FIELDS: OnceLock<Vec<&'static str>> = OnceLock::new();
    FIELDS.get_or_init(|| {
        STEP_KEYS
            .iter()
            .copied()
            .chain(super::operators::names())
            .collect()
    })
}
