//! The JSON Schema (draft-07) of rule files, for editors (`graftal schema`,
//! committed as `docs/graftal.schema.json`), and the conversion of a rule
//! file, TOML or RON, to the JSON value the schema describes.
//!
//! The schema of every operator is generated from the operator registry
//! ([`super::operators`]): its parameters' kinds, defaults, bounds and
//! documentation; the rest (steps, parameters, compounds) is written here. `tests/tooling.rs` keeps it in
//! step with the parser and compiler: every file in `rules/` validates, and
//! for every operator, `on` value and step key the schema accepts exactly the
//! steps `graftal check` accepts.
//!
//! What the schema cannot say (names that must resolve — parameters,
//! rules, compounds, `from` — expressions, and `on` for compound calls) is
//! left to `graftal check` and `graftal lint`.

use std::path::Path;

use serde_json::{json, Map, Value};

use super::compile::format_of;
use super::diagnostic::RuleError;
use super::diagnostic::SourceFile;
use super::expr::BUILTIN_CONSTANT_NAMES;
use super::operators::{self, ArgKind, Family, OperatorDef, ParamDef};
use super::property;
use super::sdf_kinds::{self, Children, KindDef, CHILDREN_KEY, CHILD_KEY, KIND_KEY, PLACEMENT};
use super::spanned::SourceFormat;
use crate::kernel::Domain;

/// Names parameters may not take: the compiler's element properties and
/// built-in constants.
fn reserved_names() -> Vec<&'static str> {
    let mut names = property::plain_names();
    names.extend(BUILTIN_CONSTANT_NAMES);
    names
}

/// Element kinds an operator's `on` may name; the first is the default.
fn allowed_on(def: &OperatorDef) -> Vec<&'static str> {
    let mut on: Vec<&'static str> = def
        .domains
        .iter()
        .map(|d| match d {
            Domain::Vert => "verts",
            Domain::Edge => "edges",
            Domain::Face => "faces",
        })
        .collect();
    if on.is_empty() {
        on.push("faces");
    }
    on
}

fn describe(mut schema: Value, text: &str) -> Value {
    if let Value::Object(map) = &mut schema {
        map.insert("description".into(), Value::String(text.into()));
    }
    schema
}

fn r(def: &str) -> Value {
    json!({ "$ref": format!("#/definitions/{def}") })
}

fn value(text: &str) -> Value {
    describe(r("value"), text)
}

fn vector(text: &str) -> Value {
    describe(r("vector"), text)
}

fn boolean(text: &str) -> Value {
    json!({ "type": "boolean", "description": text })
}

fn object(properties: Vec<(&str, Value)>, required: &[&str]) -> Value {
    let mut props = Map::new();
    for (k, v) in properties {
        props.insert(k.into(), v);
    }
    let mut o = json!({ "type": "object", "properties": props, "additionalProperties": false });
    if !required.is_empty() {
        o["required"] = json!(required);
    }
    o
}

/// The schema of one parameter, from its kind, bounds and documentation.
fn parameter(p: &ParamDef) -> Value {
    let literal_bounds = |mut number: Value| {
        if let Some(min) = p.min {
            number["minimum"] = json!(min);
        }
        if let Some(max) = p.max {
            number["maximum"] = json!(max);
        }
        number
    };
    let schema = match p.kind {
        ArgKind::Scalar | ArgKind::Element if p.min.is_some() || p.max.is_some() => {
            json!({ "anyOf": [literal_bounds(json!({ "type": "number" })),
                              { "type": "string", "minLength": 1 }] })
        }
        ArgKind::Scalar | ArgKind::Element => r("value"),
        ArgKind::Vector | ArgKind::ElementVector => r("vector"),
        ArgKind::Pair => r("pair"),
        ArgKind::ScalarList => json!({ "type": "array", "items": r("value"), "minItems": 1 }),
        ArgKind::Bool => json!({ "type": "boolean" }),
        ArgKind::Choice(names) => json!({ "enum": names }),
        ArgKind::Path => json!({ "type": "string", "minLength": 1 }),
        ArgKind::NodeCondition => r("condition"),
        ArgKind::Tree => r("sdf_tree"),
        ArgKind::Surface | ArgKind::Part => json!({ "type": "string", "minLength": 1 }),
        ArgKind::Bounds => {
            json!({ "type": "array", "items": r("vector3"), "minItems": 2, "maxItems": 2 })
        }
    };
    describe(schema, p.doc)
}

/// The schema of one signed distance node kind: `kind`, its parameters,
/// its children, the placement keys.
fn sdf_kind(kind: &KindDef) -> Value {
    let mut properties: Vec<(&str, Value)> = vec![(KIND_KEY, json!({ "const": kind.name }))];
    properties.extend(kind.params.iter().map(|p| (p.key, parameter(p))));
    match kind.children {
        Children::None => {}
        Children::One => properties.push((CHILD_KEY, describe(r("sdf_tree"), "the child tree"))),
        Children::Many { min } => properties.push((
            CHILDREN_KEY,
            json!({ "type": "array", "items": r("sdf_tree"), "minItems": min,
                    "description": "the child trees (names or tables)" }),
        )),
    }
    properties.extend(PLACEMENT.iter().map(|p| (p.key, parameter(p))));
    let mut required: Vec<&str> = vec![KIND_KEY];
    required.extend(kind.params.iter().filter(|p| p.required).map(|p| p.key));
    match kind.children {
        Children::None => {}
        Children::One => required.push(CHILD_KEY),
        Children::Many { .. } => required.push(CHILDREN_KEY),
    }
    describe(object(properties, &required), kind.summary)
}

/// The schema of an operator's value: its parameters, the required ones,
/// no two exclusive ones together, nothing else.
fn operator(def: &OperatorDef) -> Value {
    let properties: Vec<(&str, Value)> = def.params.iter().map(|p| (p.key, parameter(p))).collect();
    let required: Vec<&str> = def
        .params
        .iter()
        .filter(|p| p.required)
        .map(|p| p.key)
        .collect();
    let mut o = object(properties, &required);
    match def.exclusive {
        [] => {}
        [(a, b)] => o["not"] = json!({ "required": [a, b] }),
        pairs => {
            o["allOf"] = Value::Array(
                pairs
                    .iter()
                    .map(|(a, b)| json!({ "not": { "required": [a, b] } }))
                    .collect(),
            )
        }
    }
    o
}

/// The schema of one step. `create` admits the create operators (not in
/// compounds); `start` builds the `[start]` table instead (one create
/// operator, optionally named).
fn step(kind: StepKind) -> Value {
    let mut props = Map::new();
    props.insert(
        "name".into(),
        json!({ "type": "string", "pattern": "^[^/#]+$",
                "description": "step name (default step1, step2, …); `from` and the stats use it" }),
    );
    let ops: Vec<&'static OperatorDef> = operators::OPERATORS
        .iter()
        .filter(|op| match kind {
            StepKind::Start => op.is_create(),
            StepKind::Compound => !op.is_create(),
            StepKind::Any => true,
        })
        .collect();
    if kind != StepKind::Start {
        props.insert(
            "select".into(),
            describe(
                r("condition"),
                "condition over element properties; only matching elements are used",
            ),
        );
        props.insert(
            "from".into(),
            json!({ "type": "string", "description": "only what this earlier step (of the same list) created" }),
        );
        props.insert("on".into(), describe(r("domain"), "element kind to select"));
        props.insert(
            "rule".into(),
            json!({ "type": "string", "description": "include the named rule's steps here" }),
        );
        props.insert("compound".into(), r("compound_call"));
        props.insert(
            "repeat".into(),
            json!({ "type": "integer", "minimum": 1, "maximum": 1_000_000,
                    "description": "run the step (or included rule) this many times in a row" }),
        );
        props.insert(
            "policy".into(),
            describe(
                r("policy"),
                "G³ commands and compound calls: coinciding nodes merged, or products tested for intersection",
            ),
        );
        props.insert(
            "tolerance".into(),
            describe(r("tolerance"), "merge distance (with policy = \"merge\")"),
        );
        props.insert(
            "on_intersection".into(),
            json!({ "enum": ["skip", "cancel_compound", "cancel_rule", "error"],
                    "description": "G³ commands and compound calls: reaction to an intersecting product" }),
        );
    }
    props.insert(
        "part".into(),
        describe(
            r("part_name"),
            "the part the step's products belong to (glTF node, OBJ group)",
        ),
    );
    props.insert(
        "material".into(),
        json!({ "type": "string", "description": "a [materials.NAME] table for the step's products" }),
    );
    for op in &ops {
        props.insert(
            op.name.into(),
            describe(r(&format!("op_{}", op.name)), op.summary),
        );
    }
    // Exactly one of: an operator, `rule`, `compound`; with the keys each allows.
    let mut choices = Vec::new();
    let no = |keys: &[&str]| -> Value {
        Value::Object(keys.iter().map(|k| ((*k).into(), json!(false))).collect())
    };
    for op in &ops {
        let mut choice = json!({ "required": [op.name] });
        if kind == StepKind::Start {
            choices.push(choice);
            continue;
        }
        let restricted = if op.is_create() || op.family == Family::WholeMesh {
            no(&[
                "select",
                "from",
                "on",
                "policy",
                "tolerance",
                "on_intersection",
            ])
        } else {
            let mut p = if op.family == Family::Command {
                Map::new()
            } else {
                match no(&["policy", "tolerance", "on_intersection"]) {
                    Value::Object(m) => m,
                    _ => unreachable!(),
                }
            };
            // `"vertices"` is accepted for `"verts"`.
            let mut on: Vec<&str> = allowed_on(op);
            if on.contains(&"verts") {
                on.push("vertices");
            }
            p.insert("on".into(), json!({ "enum": on }));
            Value::Object(p)
        };
        choice["properties"] = restricted;
        if op.id == operators::OpId::Assign {
            // `assign` changes nothing without one of them.
            choice["anyOf"] = json!([{ "required": ["part"] }, { "required": ["material"] }]);
        }
        choices.push(choice);
    }
    if kind != StepKind::Start {
        choices.push(json!({ "required": ["rule"],
            "properties": no(&["select", "from", "on", "policy", "tolerance"]) }));
        choices.push(json!({ "required": ["compound"] }));
    }
    let mut s = json!({
        "type": "object",
        "properties": props,
        "additionalProperties": false,
        "oneOf": choices,
    });
    if kind != StepKind::Start {
        s["dependencies"] = json!({
            "tolerance": { "required": ["policy"], "properties": { "policy": { "const": "merge" } } }
        });
    }
    s
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum StepKind {
    Start,
    Any,
    Compound,
}

fn steps_list(item: &str) -> Value {
    json!({ "type": "array", "items": r(item) })
}

/// The JSON Schema of rule files.
pub fn schema() -> Value {
    let mut definitions = Map::new();
    definitions.insert(
        "value".into(),
        json!({ "type": ["number", "string"], "minLength": 1,
                "description": "a number or an expression string" }),
    );
    definitions.insert(
        "spread".into(),
        json!({ "anyOf": [ { "type": "number", "minimum": 0 }, { "type": "string", "minLength": 1 } ],
                "description": "variation σ: adds U(−σ, σ) per primitive (0)" }),
    );
    definitions.insert(
        "vector".into(),
        json!({ "anyOf": [
            r("value"),
            { "type": "array", "items": r("value"), "minItems": 3, "maxItems": 3 } ],
            "description": "[x, y, z] (numbers or expressions), or one value for all three" }),
    );
    definitions.insert(
        "vector3".into(),
        json!({ "type": "array", "items": r("value"), "minItems": 3, "maxItems": 3 }),
    );
    definitions.insert(
        "nurbs_surface".into(),
        json!({
            "type": "object",
            "description": "a NURBS surface (thesis 002 §1.2): degree, net size, control points (a list, or [x, y, z] expressions over the net indices i and j), weights, knots; a curve (one size); or a lathe or sweep of named curves",
            "additionalProperties": false,
            "properties": {
                "degree": { "anyOf": [r("value"), r("pair")], "description": "degree along u and v, or one for both (required but for a lathe or sweep of named curves)" },
                "size": { "anyOf": [r("pair"), r("value")], "description": "control points along u and v; one number: a curve's point count" },
                "points": { "anyOf": [
                    { "type": "array", "items": r("vector3"), "minItems": 4 },
                    { "type": "array", "items": r("value"), "minItems": 3, "maxItems": 3 } ],
                    "description": "control points row-major (i along u), or one [x, y, z] of expressions over i and j" },
                "weights": { "anyOf": [ r("value"), { "type": "array", "items": r("value") } ],
                    "description": "weights (default 1): a list, or an expression over i and j" },
                "knots_u": { "anyOf": [ { "const": "clamped_uniform" }, { "type": "array", "items": r("value") } ],
                    "description": "knots along u (\"clamped_uniform\")" },
                "knots_v": { "anyOf": [ { "const": "clamped_uniform" }, { "type": "array", "items": r("value") } ],
                    "description": "knots along v (\"clamped_uniform\")" },
                "profile": { "anyOf": [
                    { "type": "array", "items": { "anyOf": [ r("value"),
                        { "type": "array", "items": r("value"), "minItems": 2, "maxItems": 2 } ] } },
                    { "type": "string", "minLength": 1 } ],
                    "description": "instead of points: [r, z] points revolved about +Z (a lathe), one [r, z] of expressions over j, or the name of a curve (a lathe, or with `path` a sweep)" },
                "knots": { "anyOf": [ { "const": "clamped_uniform" }, { "type": "array", "items": r("value") } ],
                    "description": "a curve's knots (\"clamped_uniform\")" },
                "path": { "type": "string", "minLength": 1, "description": "the curve a named profile is swept along" },
                "orient": { "enum": ["follow", "fixed"], "description": "a sweep's profile turns with the path (follow) or is only translated (fixed)" },
                "path_tolerance": describe(r("value"), "how far a follow sweep may stray from a true rotation-minimizing sweep (0.001)"),
                "patches": { "anyOf": [
                    { "type": "string", "minLength": 1 },
                    { "type": "array", "items": { "type": "string", "minLength": 1 }, "minItems": 1 } ],
                    "description": "a patch set: a patch file (.bpt or OBJ free-form surfaces) beside the rule file, or the names of [nurbs.NAME] surfaces; shared borders are found and meshed without cracks" },
                "joins": { "type": "array",
                    "items": { "type": "array", "items": { "type": "string", "pattern": "^.+\\.(u0|u1|v0|v1)$" }, "minItems": 2, "maxItems": 2 },
                    "description": "a patch set's borders declared shared whose control points only nearly agree: pairs [\"PATCH.SIDE\", \"PATCH.SIDE\"] (PATCH a listed name or a file's patch number from 0; SIDE u0, u1, v0, v1)" }
            }
        }),
    );
    definitions.insert(
        "sdf_tree".into(),
        json!({ "anyOf": [ { "type": "string", "minLength": 1 }, r("sdf_node") ],
                "description": "the name of an [sdf.NAME] tree, or a tree table with a `kind`" }),
    );
    definitions.insert(
        "sdf_node".into(),
        json!({ "oneOf": sdf_kinds::KINDS.iter().map(sdf_kind).collect::<Vec<_>>() }),
    );
    definitions.insert(
        "pair".into(),
        json!({ "type": "array", "items": r("value"), "minItems": 2, "maxItems": 2 }),
    );
    definitions.insert(
        "condition".into(),
        json!({ "type": "string", "minLength": 1,
                "description": "expression over parameters and element properties; non-zero is true" }),
    );
    definitions.insert(
        "part_name".into(),
        json!({ "type": "string", "pattern": "^[A-Za-z0-9_.-]{1,64}$" }),
    );
    let unit = json!({ "type": "number", "minimum": 0, "maximum": 1 });
    let color = |alpha: bool| {
        let max = if alpha { 4 } else { 3 };
        let hex = if alpha {
            "^#([0-9a-fA-F]{3}|[0-9a-fA-F]{6}|[0-9a-fA-F]{8})$"
        } else {
            "^#([0-9a-fA-F]{3}|[0-9a-fA-F]{6})$"
        };
        json!({ "oneOf": [
            { "type": "string", "pattern": hex, "description": "sRGB hex" },
            { "type": "array", "items": unit, "minItems": 3, "maxItems": max, "description": "linear [0, 1]" }
        ] })
    };
    definitions.insert(
        "material".into(),
        json!({ "type": "object", "additionalProperties": false, "properties": {
            "base_color": describe(color(true), "base colour (\"#rrggbb[aa]\" sRGB, or linear numbers)"),
            "metallic": describe(unit.clone(), "metalness (0)"),
            "roughness": describe(unit.clone(), "perceptual roughness (0.6)"),
            "emissive": describe(color(false), "emitted colour (black)"),
            "alpha_mode": { "enum": ["opaque", "mask", "blend"] },
            "alpha_cutoff": describe(unit.clone(), "with alpha_mode = \"mask\" (0.5)"),
            "double_sided": { "type": "boolean", "description": "default: only when its faces are not closed shells" }
        } }),
    );
    definitions.insert(
        "normals".into(),
        json!({ "oneOf": [
            { "enum": ["flat", "smooth"] },
            { "type": "object", "additionalProperties": false, "required": ["crease"],
              "properties": { "crease": { "type": "number", "minimum": 0, "maximum": 180,
                  "description": "edges sharper than this many degrees stay sharp" } } }
        ] }),
    );
    definitions.insert(
        "uv".into(),
        json!({ "oneOf": [
            { "const": "none" },
            { "type": "object", "additionalProperties": false, "required": ["projection"],
              "properties": {
                "projection": { "enum": ["box", "planar", "cylindrical", "surface"] },
                "size": { "type": "number", "exclusiveMinimum": 0, "description": "model length one texture repeat covers (1)" },
                "axis": { "enum": ["x", "y", "z"], "description": "planar and cylindrical: the axis (z)" }
              } }
        ] }),
    );
    let channels = json!({ "type": "array", "minItems": 3, "maxItems": 3,
        "items": { "oneOf": [ { "type": "number" }, r("condition") ] } });
    definitions.insert(
        "color".into(),
        json!({ "type": "object", "additionalProperties": false, "minProperties": 1, "maxProperties": 1,
                "description": "face colour over face properties, channels in [0, 1] (sRGB; hue in turns)",
                "properties": { "hsv": channels.clone(), "rgb": channels } }),
    );
    definitions.insert(
        "part".into(),
        json!({ "type": "object", "additionalProperties": false, "properties": {
            "material": { "type": "string" },
            "normals": r("normals"),
            "uv": r("uv"),
            "color": r("color")
        } }),
    );
    definitions.insert(
        "domain".into(),
        json!({ "enum": ["verts", "vertices", "edges", "faces"] }),
    );
    definitions.insert(
        "policy".into(),
        json!({ "enum": ["none", "merge", "intersect"] }),
    );
    definitions.insert(
        "tolerance".into(),
        json!({ "type": "number", "minimum": 0, "maximum": 1 }),
    );
    let mut param_table = object(
        vec![
            (
                "uniform",
                describe(r("pair"), "uniform real in [low, high)"),
            ),
            (
                "normal",
                describe(r("pair"), "normal [mean, standard deviation]"),
            ),
            (
                "int",
                describe(r("pair"), "uniform integer in [low, high], inclusive"),
            ),
            (
                "choice",
                json!({ "type": "array", "items": r("value"), "minItems": 1,
                               "description": "one of these values" }),
            ),
            (
                "weights",
                json!({ "type": "array", "items": { "type": "number", "minimum": 0 },
                                "description": "weights of the choices" }),
            ),
            (
                "clamp",
                describe(r("pair"), "clamp the drawn value into [min, max]"),
            ),
        ],
        &[],
    );
    param_table["oneOf"] = json!([
        { "required": ["uniform"] }, { "required": ["normal"] },
        { "required": ["int"] }, { "required": ["choice"] } ]);
    param_table["dependencies"] = json!({ "weights": ["choice"] });
    definitions.insert(
        "param".into(),
        json!({ "anyOf": [ { "type": "number" }, { "type": "string", "minLength": 1 }, param_table ],
                "description": "a constant, an expression over other parameters, or a distribution" }),
    );
    let frame = |with_name: bool| {
        let mut p = vec![
            (
                "relative",
                boolean("frame and sizes from the initial primitive"),
            ),
            ("length", value("the compound's length (Table 3.2)")),
            ("radius", value("the compound's radius")),
            ("heading", vector("the compound's heading")),
            ("up", vector("the compound's up vector")),
        ];
        if with_name {
            p.insert(
                0,
                (
                    "name",
                    json!({ "type": "string", "description": "the compound to apply" }),
                ),
            );
        }
        p
    };
    definitions.insert(
        "compound_call".into(),
        json!({ "anyOf": [ { "type": "string" }, object(frame(true), &["name"]) ],
                "description": "apply a compound command: its name, or { name = …, length = … } overriding its parameters" }),
    );
    let mut compound_props = frame(false);
    compound_props.insert(
        0,
        ("on", describe(r("domain"), "kind of the initial primitive")),
    );
    compound_props.insert(
        1,
        (
            "select",
            describe(r("condition"), "which primitives it starts from"),
        ),
    );
    compound_props.push((
        "step",
        json!({ "type": "array", "items": r("compound_step"), "minItems": 1 }),
    ));
    compound_props.push((
        "steps",
        json!({ "type": "array", "items": r("compound_step"), "minItems": 1 }),
    ));
    let mut compound = object(compound_props, &["on"]);
    compound["oneOf"] = json!([{ "required": ["step"] }, { "required": ["steps"] }]);
    definitions.insert("compound".into(), compound);
    let mut rule = object(
        vec![("step", steps_list("step")), ("steps", steps_list("step"))],
        &[],
    );
    rule["not"] = json!({ "required": ["step", "steps"] });
    definitions.insert("rule".into(), rule);
    definitions.insert("step".into(), step(StepKind::Any));
    definitions.insert("compound_step".into(), step(StepKind::Compound));
    definitions.insert("start".into(), step(StepKind::Start));
    for op in operators::OPERATORS {
        definitions.insert(format!("op_{}", op.name), operator(op));
    }

    let mut root = object(
        vec![
            (
                "seed",
                json!({ "type": "integer", "minimum": 0,
                             "description": "default seed; `graftal run --seed N` overrides it" }),
            ),
            (
                "params",
                json!({
                "type": "object",
                "description": "named parameters: constants, expressions, distributions",
                "propertyNames": { "pattern": "^[A-Za-z_][A-Za-z0-9_]*$", "not": { "enum": reserved_names() } },
                "additionalProperties": r("param") }),
            ),
            (
                "start",
                describe(r("start"), "the start shape: one create operator"),
            ),
            (
                "step",
                describe(steps_list("step"), "operators applied in order"),
            ),
            (
                "steps",
                describe(
                    steps_list("step"),
                    "operators applied in order (alias of `step`)",
                ),
            ),
            (
                "rules",
                json!({ "type": "object", "additionalProperties": r("rule"),
                              "description": "named step lists, included by rule = \"NAME\"" }),
            ),
            (
                "compound",
                json!({
                "type": "object",
                "description": "compound commands, applied by compound = \"NAME\"",
                "propertyNames": { "pattern": "^[A-Za-z_][A-Za-z0-9_]*$" },
                "additionalProperties": r("compound") }),
            ),
            (
                "sdf",
                json!({
                "type": "object",
                "description": "signed distance trees, used by the sdf operators' `tree` and by other trees' children",
                "additionalProperties": r("sdf_node") }),
            ),
            (
                "nurbs",
                json!({
                "type": "object",
                "description": "parametric surfaces, used by the nurbs operator's `surface`",
                "additionalProperties": r("nurbs_surface") }),
            ),
            (
                "materials",
                json!({ "type": "object", "description": "PBR materials, named by parts and steps",
                        "propertyNames": r("part_name"), "additionalProperties": r("material") }),
            ),
            (
                "parts",
                json!({ "type": "object", "description": "part settings: material, normals, uv",
                        "propertyNames": r("part_name"), "additionalProperties": r("part") }),
            ),
            (
                "material",
                json!({ "type": "string", "description": "material of everything no part or step gives one" }),
            ),
            (
                "normals",
                describe(
                    r("normals"),
                    "shading normals of parts that set none (\"flat\")",
                ),
            ),
            (
                "uv",
                describe(
                    r("uv"),
                    "texture coordinates of parts that set none (\"none\")",
                ),
            ),
            (
                "color",
                describe(r("color"), "face colours of parts that set none"),
            ),
            (
                "policy",
                describe(r("policy"), "default policy of G³ commands (\"none\")"),
            ),
            (
                "on_intersection",
                json!({ "enum": ["skip", "error"],
                "description": "default reaction to an intersecting product (\"skip\")" }),
            ),
            (
                "tolerance",
                describe(r("tolerance"), "merge distance in model units (1e-6)"),
            ),
        ],
        &[],
    );
    root["not"] = json!({ "required": ["step", "steps"] });
    let mut doc = Map::new();
    doc.insert(
        "$schema".into(),
        json!("http://json-schema.org/draft-07/schema#"),
    );
    doc.insert("title".into(), json!("graftal rule file"));
    doc.insert(
        "description".into(),
        json!("A graftal rule file (TOML or RON): parameters, a start shape, steps, rules and compound commands. See docs/rules.md."),
    );
    if let Value::Object(root) = root {
        doc.extend(root);
    }
    doc.insert("definitions".into(), Value::Object(definitions));
    Value::Object(doc)
}

/// The schema as `graftal schema` prints it (and `docs/graftal.schema.json`
/// holds): pretty JSON with a final newline.
pub fn schema_text() -> String {
    let mut text = serde_json::to_string_pretty(&schema()).expect("schema serializes");
    text.push('\n');
    text
}

/// Rule text as the JSON value the schema describes.
pub fn to_json(text: &str, format: SourceFormat) -> Result<Value, String> {
    match format {
        SourceFormat::Toml => {
            let v: toml::Value = toml::from_str(text).map_err(|e| e.to_string())?;
            serde_json::to_value(v).map_err(|e| e.to_string())
        }
        SourceFormat::Ron => super::ron::parse(text)
            .map(ron_to_json)
            .map_err(|e| e.to_string()),
    }
}

/// A rule file as the JSON value the schema describes.
pub fn file_to_json(file: &SourceFile) -> Result<Value, RuleError> {
    let format = format_of(Path::new(&file.name)).map_err(|m| RuleError::at(file, None, m))?;
    to_json(&file.text, format).map_err(|m| RuleError::at(file, None, m))
}

fn ron_to_json(v: super::ron::Value) -> Value {
    use super::ron::Kind;
    match v.kind {
        Kind::Bool(b) => Value::Bool(b),
        Kind::Char(c) => Value::String(c.to_string()),
        Kind::Str(s) => Value::String(s),
        // Enum variants (`on: faces`) are strings in the TOML form.
        Kind::Ident(name) if name == "None" => Value::Null,
        Kind::Ident(name) => Value::String(name),
        Kind::Integer(x) => match i64::try_from(x) {
            Ok(x) => json!(x),
            Err(_) => u64::try_from(x).map_or(json!(x as f64), |x| json!(x)),
        },
        Kind::Float(x) => json!(x),
        Kind::Tuple(Some(name), mut items) if name == "Some" && items.len() == 1 => {
            ron_to_json(items.pop().expect("one item"))
        }
        Kind::List(items) | Kind::Tuple(_, items) => {
            Value::Array(items.into_iter().map(ron_to_json).collect())
        }
        // `()` is an empty struct: `triangulate: ()`.
        Kind::Unit => Value::Object(Map::new()),
        Kind::Struct(_, entries) | Kind::Map(entries) => {
            let mut out = Map::new();
            for (k, v) in entries {
                let key = match ron_to_json(k) {
                    Value::String(s) => s,
                    other => other.to_string(),
                };
                // An absent optional key and `None` mean the same.
                if matches!(&v.kind, Kind::Ident(n) if n == "None") {
                    continue;
                }
                out.insert(key, ron_to_json(v));
            }
            Value::Object(out)
        }
    }
}
