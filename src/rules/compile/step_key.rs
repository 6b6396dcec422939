//! What names a step's random stream (issue 33): its `name`, or — when it
//! has none — a hash of what it says. Keys by position ("step3") re-rolled
//! every later step when one was inserted; a key by content moves only
//! when the step itself is edited.
//!
//! The content is the step as written minus what does not change what it
//! does to one primitive: its name (the key takes it instead), `repeat`
//! (each copy is told apart by `#k`, so raising the count keeps the
//! earlier copies' draws) and every byte position. Tables are read in key
//! order, and TOML's `"faces"` and RON's `faces` are one choice, so a step
//! keeps its key across formatting, comments and either syntax.

use std::fmt::Write as _;

use crate::rules::ast::{self, ArgValue, Args, Scalar, VectorSpec};
use crate::rules::random::stream_key;

/// The key name of an unnamed operator or compound step: `~` and 16 hex
/// digits of its content's hash.
pub fn content_name(step: &ast::Step) -> String {
    format!("~{:016x}", stream_key(&content(step)))
}

/// The canonical text of a step's content (see the module doc).
pub fn content(step: &ast::Step) -> String {
    let mut out = String::new();
    let mut field = |key: &str, value: Option<String>| {
        if let Some(value) = value {
            let _ = write!(out, "{key}={value};");
        }
    };
    field("select", step.select.as_ref().map(|s| quoted(&s.value)));
    field("from", step.from.as_ref().map(|s| quoted(&s.value)));
    field("on", step.on.as_ref().map(|s| format!("{:?}", s.value)));
    field(
        "op",
        step.op
            .as_ref()
            .map(|(key, args)| format!("{}{}", quoted(&key.value), table(&args.value))),
    );
    field("rule", step.rule.as_ref().map(|s| quoted(&s.value)));
    field(
        "compound",
        step.compound
            .as_ref()
            .map(|(_, call)| compound(&call.value)),
    );
    field(
        "policy",
        step.policy.as_ref().map(|s| format!("{:?}", s.value)),
    );
    field(
        "tolerance",
        step.tolerance.as_ref().map(|s| number(s.value)),
    );
    field(
        "on_intersection",
        step.on_intersection
            .as_ref()
            .map(|s| format!("{:?}", s.value)),
    );
    field("part", step.part.as_ref().map(|s| quoted(&s.value)));
    field("material", step.material.as_ref().map(|s| quoted(&s.value)));
    out
}

fn quoted(text: &str) -> String {
    format!("{text:?}")
}

/// A number by its bits: `1` and `1.0` are one number, `-0.0` another.
fn number(x: f64) -> String {
    format!("#{:016x}", x.to_bits())
}

fn table(args: &Args) -> String {
    let mut entries: Vec<(&str, String)> = args
        .0
        .iter()
        .map(|(k, v)| (k.value.as_str(), value(&v.value)))
        .collect();
    entries.sort();
    let body: Vec<String> = entries
        .into_iter()
        .map(|(k, v)| format!("{k:?}:{v}"))
        .collect();
    format!("{{{}}}", body.join(","))
}

fn value(v: &ArgValue) -> String {
    match v {
        ArgValue::Number(x) => number(*x),
        // A bare RON name and a TOML string are one choice.
        ArgValue::Text(t) | ArgValue::Name(t) => quoted(t),
        ArgValue::Bool(b) => b.to_string(),
        ArgValue::List(items) => {
            let items: Vec<String> = items.iter().map(|i| value(&i.value)).collect();
            format!("[{}]", items.join(","))
        }
        ArgValue::Table(args) => table(args),
    }
}

fn scalar(s: &Scalar) -> String {
    match s {
        Scalar::Number(x) => number(*x),
        Scalar::Expr(e) => quoted(e),
    }
}

fn compound(call: &ast::CompoundCall) -> String {
    let f = &call.frame;
    let vector = |v: &Option<ast::Vector>| {
        v.as_ref().map_or_else(String::new, |v| match &v.value {
            VectorSpec::Components(c) => {
                format!(
                    "[{},{},{}]",
                    scalar(&c[0].value),
                    scalar(&c[1].value),
                    scalar(&c[2].value)
                )
            }
            VectorSpec::Uniform(s) => scalar(s),
        })
    };
    let opt = |v: &Option<ast::Value>| v.as_ref().map_or_else(String::new, |v| scalar(&v.value));
    format!(
        "{}(relative={:?},length={},radius={},heading={},up={})",
        quoted(&call.name.value),
        f.relative.as_ref().map(|r| r.value),
        opt(&f.length),
        opt(&f.radius),
        vector(&f.heading),
        vector(&f.up)
    )
}

#[cfg(test)]
mod tests {
    use crate::rules::compile::parse;
    use crate::rules::diagnostic::SourceFile;
    use crate::rules::spanned::SourceFormat;

    fn contents(text: &str, format: SourceFormat) -> Vec<String> {
        let file = SourceFile {
            name: "t".into(),
            text: text.into(),
        };
        let ast = parse(&file, format).unwrap();
        ast.steps.iter().map(super::content).collect()
    }

    #[test]
    fn content_ignores_names_repeats_layout_and_syntax() {
        let a = contents(
            "[[step]]\nname = \"a\"\nselect = \"area > 1\"\nextrude_faces = { offset = [0, 0, 1], keep_original = true }\n",
            SourceFormat::Toml,
        );
        let b = contents(
            "# moved\n[[step]]\nrepeat = 3\n\nselect = \"area > 1\"\n  extrude_faces = {keep_original=true,   offset=[0.0, 0, 1.0]}\n",
            SourceFormat::Toml,
        );
        assert_eq!(a, b);
        let ron = contents(
            "(step: [(select: \"area > 1\", extrude_faces: (offset: (0, 0, 1), keep_original: true))])",
            SourceFormat::Ron,
        );
        assert_eq!(a, ron);
        // What it does is in the content.
        for other in [
            "[[step]]\nselect = \"area > 2\"\nextrude_faces = { offset = [0, 0, 1], keep_original = true }\n",
            "[[step]]\nselect = \"area > 1\"\nextrude_faces = { offset = [0, 0, -1], keep_original = true }\n",
            "[[step]]\nselect = \"area > 1\"\npart = \"p\"\nextrude_faces = { offset = [0, 0, 1], keep_original = true }\n",
        ] {
            assert_ne!(a, contents(other, SourceFormat::Toml), "{other}");
        }
    }
}
