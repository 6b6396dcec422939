//! How the model looks in its files (issue 16): `[materials.NAME]`,
//! `[parts.NAME]` and the file's `material`, `normals` and `uv`, compiled
//! into the program's [`Look`]. Values are constants (a material does not
//! change between variants); every one is checked here and located.

use std::ops::Range;

use super::{closest_in, Compiler};
use crate::geom::material::{parse_hex_color, AlphaMode, Material};
use crate::geom::uv::{Projection, UvMapping};
use crate::rules::ast::{self, ArgValue};
use crate::rules::diagnostic::RuleError;
use crate::rules::program::{Look, PartLook};
use crate::rules::spanned::Spanned;

/// The keys of a `[materials.NAME]` table.
pub const MATERIAL_KEYS: [&str; 7] = [
    "base_color",
    "metallic",
    "roughness",
    "emissive",
    "alpha_mode",
    "alpha_cutoff",
    "double_sided",
];

/// The keys of a `[parts.NAME]` table.
pub const PART_KEYS: [&str; 4] = ["material", "normals", "uv", "color"];

/// The keys of a `uv = { … }` table.
const UV_KEYS: [&str; 3] = ["projection", "size", "axis"];

/// Crease angle of `normals = "smooth"`: every edge is smoothed.
const SMOOTH_CREASE: f64 = 180.0;

/// A part's name as written (file stem of the rule file for part 0).
pub fn default_part_name(file: &str) -> String {
    let stem = std::path::Path::new(file)
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("model");
    if Material::valid_name(stem) {
        stem.to_owned()
    } else {
        "model".to_owned()
    }
}

impl Compiler<'_> {
    /// The file's materials (in name order) and parts: part 0 is the
    /// default part, then the `[parts.NAME]` tables in name order; steps
    /// add the parts they name first, through [`Look::part_index`].
    pub(super) fn compile_look(&self, ast: &ast::RuleFile) -> Result<Look, RuleError> {
        // Name order: TOML keeps no table order, and one canonical order
        // keeps both formats (and the files) identical.
        let mut tables: Vec<_> = ast.materials.0.iter().collect();
        tables.sort_by(|a, b| a.0.value.cmp(&b.0.value));
        let mut materials = Vec::with_capacity(tables.len());
        for (name, table) in tables {
            self.check_name(name, "material")?;
            if materials.iter().any(|m: &Material| m.name == name.value) {
                return Err(self.error(
                    name.span.clone(),
                    format!("material `{}` is defined twice", name.value),
                ));
            }
            materials.push(self.material(&name.value, table)?);
        }
        let mut look = Look {
            parts: Vec::new(),
            materials,
            colors: Vec::new(),
        };
        let material = match &ast.material {
            Some(m) => Some(self.material_reference(&look, m)?),
            None => None,
        };
        let crease = match &ast.normals {
            Some(n) => self.normals(n)?,
            None => 0.0,
        };
        let uv = match &ast.uv {
            Some(u) => self.uv(u)?,
            None => None,
        };
        let color = match &ast.color {
            Some(c) => Some(self.color_spec(&mut look, c)?),
            None => None,
        };
        let file_default = PartLook {
            name: default_part_name(&self.file.name),
            material,
            crease,
            uv,
            color,
        };
        look.parts.push(file_default.clone());
        let mut tables: Vec<_> = ast.parts.0.iter().collect();
        tables.sort_by(|a, b| a.0.value.cmp(&b.0.value));
        for (name, table) in tables {
            self.check_name(name, "part")?;
            if look.parts[1..].iter().any(|p| p.name == name.value) {
                return Err(self.error(
                    name.span.clone(),
                    format!("part `{}` is defined twice", name.value),
                ));
            }
            let mut part = PartLook {
                name: name.value.clone(),
                ..file_default.clone()
            };
            for (key, value) in &table.value.0 {
                match key.value.as_str() {
                    "material" => {
                        let text = self.text(value, "the name of a [materials.NAME] table")?;
                        let written = Spanned {
                            value: text.to_owned(),
                            span: value.span.clone(),
                        };
                        part.material = Some(self.material_reference(&look, &written)?);
                    }
                    "normals" => part.crease = self.normals(value)?,
                    "uv" => part.uv = self.uv(value)?,
                    "color" => part.color = Some(self.color_spec(&mut look, value)?),
                    other => return Err(self.unknown_key(key, other, &PART_KEYS, "a part")),
                }
            }
            // `[parts.NAME]` with the default part's own name sets part 0.
            if part.name == look.parts[0].name {
                look.parts[0] = part;
            } else {
                look.parts.push(part);
            }
        }
        Ok(look)
    }

    /// The index of the material `written` names.
    pub(super) fn material_reference(
        &self,
        look: &Look,
        written: &Spanned<String>,
    ) -> Result<u32, RuleError> {
        let names: Vec<&str> = look.materials.iter().map(|m| m.name.as_str()).collect();
        match names.iter().position(|n| *n == written.value) {
            Some(i) => Ok(i as u32),
            None => {
                let e = self.error(
                    written.span.clone(),
                    format!("no material named `{}`", written.value),
                );
                Err(match closest_in(&written.value, &names) {
                    Some(k) => e.with_help(format!("did you mean `{}`?", names[k])),
                    None if names.is_empty() => e.with_help(
                        "define it as a table [materials.NAME] with base_color, metallic, roughness",
                    ),
                    None => e.with_help(format!("materials: {}", names.join(", "))),
                })
            }
        }
    }

    /// Checks a part or material name (it becomes a node, group or
    /// material name in the files).
    pub(super) fn check_name(&self, name: &Spanned<String>, what: &str) -> Result<(), RuleError> {
        if Material::valid_name(&name.value) {
            Ok(())
        } else {
            Err(self.error(
                name.span.clone(),
                format!(
                    "`{}` is not a valid {what} name: 1 to 64 ASCII letters, digits, `_`, `-` or `.`",
                    name.value
                ),
            ))
        }
    }

    fn material(&self, name: &str, table: &Spanned<ast::Args>) -> Result<Material, RuleError> {
        let mut m = Material {
            name: name.to_owned(),
            ..Material::fallback()
        };
        let mut cutoff: Option<(f64, Option<Range<usize>>)> = None;
        let mut mode: Option<(&str, Option<Range<usize>>)> = None;
        for (key, value) in &table.value.0 {
            match key.value.as_str() {
                "base_color" => m.base_color = self.color(value, true)?,
                "emissive" => {
                    let c = self.color(value, false)?;
                    m.emissive = [c[0], c[1], c[2]];
                }
                "metallic" => m.metallic = self.unit(value)?,
                "roughness" => m.roughness = self.unit(value)?,
                "alpha_cutoff" => cutoff = Some((self.unit(value)?, value.span.clone())),
                "double_sided" => match value.value {
                    ArgValue::Bool(b) => m.double_sided = Some(b),
                    ref other => {
                        return Err(self.error(
                            value.span.clone(),
                            format!("invalid type: {}, expected true or false", other.describe()),
                        ))
                    }
                },
                "alpha_mode" => {
                    let text = self.text(value, "\"opaque\", \"mask\" or \"blend\"")?;
                    mode = Some((text, value.span.clone()));
                }
                other => return Err(self.unknown_key(key, other, &MATERIAL_KEYS, "a material")),
            }
        }
        m.alpha = match mode {
            None | Some(("opaque", _)) => AlphaMode::Opaque,
            Some(("mask", _)) => AlphaMode::Mask(cutoff.as_ref().map_or(0.5, |c| c.0)),
            Some(("blend", _)) => AlphaMode::Blend,
            Some((other, span)) => {
                return Err(self.error(
                    span,
                    format!(
                        "unknown alpha_mode `{other}`, expected \"opaque\", \"mask\" or \"blend\""
                    ),
                ))
            }
        };
        if let (Some((_, span)), false) = (&cutoff, matches!(m.alpha, AlphaMode::Mask(_))) {
            return Err(self
                .error(
                    span.clone(),
                    "`alpha_cutoff` applies only to alpha_mode = \"mask\"",
                )
                .with_help("add alpha_mode = \"mask\", or remove alpha_cutoff"));
        }
        Ok(m)
    }

    /// A colour: sRGB hex (`"#c8a27a"`, with alpha when `alpha`), or 3 (or
    /// 4) linear numbers in [0, 1], as glTF stores them.
    fn color(&self, value: &Spanned<ArgValue>, alpha: bool) -> Result<[f64; 4], RuleError> {
        let expected = if alpha {
            "an sRGB hex colour such as \"#c8a27a\" or \"#c8a27a80\", or [r, g, b] or [r, g, b, a] in linear [0, 1]"
        } else {
            "an sRGB hex colour such as \"#ff8000\", or [r, g, b] in linear [0, 1]"
        };
        let bad = |this: &Self| this.error(value.span.clone(), format!("expected {expected}"));
        match &value.value {
            ArgValue::Text(text) => match parse_hex_color(text) {
                Some(c) if alpha || text.len() <= 7 => Ok(c),
                _ => Err(bad(self)),
            },
            ArgValue::List(items) if items.len() == 3 || (alpha && items.len() == 4) => {
                let mut c = [1.0; 4];
                for (slot, item) in c.iter_mut().zip(items) {
                    *slot = self.unit(item)?;
                }
                Ok(c)
            }
            _ => Err(bad(self)),
        }
    }

    /// A constant in [0, 1].
    fn unit(&self, value: &Spanned<ArgValue>) -> Result<f64, RuleError> {
        match value.value {
            ArgValue::Number(x) if (0.0..=1.0).contains(&x) => Ok(x),
            ArgValue::Number(x) => {
                Err(self.error(value.span.clone(), format!("{x} is outside [0, 1]")))
            }
            ref other => Err(self.error(
                value.span.clone(),
                format!(
                    "invalid type: {}, expected a number in [0, 1]",
                    other.describe()
                ),
            )),
        }
    }

    fn text<'v>(&self, value: &'v Spanned<ArgValue>, expected: &str) -> Result<&'v str, RuleError> {
        match &value.value {
            ArgValue::Text(t) | ArgValue::Name(t) => Ok(t),
            other => Err(self.error(
                value.span.clone(),
                format!("invalid type: {}, expected {expected}", other.describe()),
            )),
        }
    }

    /// `normals`: the crease angle in degrees (0 = flat).
    fn normals(&self, value: &Spanned<ArgValue>) -> Result<f64, RuleError> {
        let expected = "\"flat\", \"smooth\" or { crease = DEGREES }";
        match &value.value {
            ArgValue::Text(t) | ArgValue::Name(t) => match t.as_str() {
                "flat" => Ok(0.0),
                "smooth" => Ok(SMOOTH_CREASE),
                other => Err(self.error(
                    value.span.clone(),
                    format!("unknown normals `{other}`, expected {expected}"),
                )),
            },
            ArgValue::Table(args) => {
                let mut crease = None;
                for (key, v) in &args.0 {
                    if key.value != "crease" {
                        return Err(self.unknown_key(key, &key.value, &["crease"], "normals"));
                    }
                    crease = Some(match v.value {
                        ArgValue::Number(x) if (0.0..=180.0).contains(&x) => x,
                        _ => {
                            return Err(self.error(
                                v.span.clone(),
                                "`crease` is an angle in degrees, from 0 (flat) to 180 (smooth everywhere)",
                            ))
                        }
                    });
                }
                crease.ok_or_else(|| {
                    self.error(
                        value.span.clone(),
                        "`normals` table needs `crease = DEGREES`",
                    )
                })
            }
            other => Err(self.error(
                value.span.clone(),
                format!("invalid type: {}, expected {expected}", other.describe()),
            )),
        }
    }

    /// `uv`: `"none"` or a projection table.
    fn uv(&self, value: &Spanned<ArgValue>) -> Result<Option<UvMapping>, RuleError> {
        let expected = "\"none\" or { projection = \"box\" | \"planar\" | \"cylindrical\" | \"surface\", size = LENGTH, axis = \"x\" | \"y\" | \"z\" }";
        let args = match &value.value {
            ArgValue::Text(t) | ArgValue::Name(t) if t == "none" => return Ok(None),
            ArgValue::Table(args) => args,
            other => {
                return Err(self.error(
                    value.span.clone(),
                    format!("invalid {}, expected {expected}", other.describe()),
                ))
            }
        };
        let (mut projection, mut size, mut axis) = (None, 1.0, 2usize);
        let mut axis_span = None;
        for (key, v) in &args.0 {
            match key.value.as_str() {
                "projection" => {
                    projection = Some((
                        self.text(v, "\"box\", \"planar\", \"cylindrical\" or \"surface\"")?,
                        v.span.clone(),
                    ))
                }
                "size" => {
                    match v.value {
                        ArgValue::Number(x) if x > 0.0 && x.is_finite() => size = x,
                        _ => return Err(self.error(
                            v.span.clone(),
                            "`size` is the model length one texture repeat covers, a number > 0",
                        )),
                    }
                }
                "axis" => {
                    axis_span = v.span.clone();
                    axis = match self.text(v, "\"x\", \"y\" or \"z\"")? {
                        "x" => 0,
                        "y" => 1,
                        "z" => 2,
                        other => {
                            return Err(self.error(
                                v.span.clone(),
                                format!("unknown axis `{other}`, expected \"x\", \"y\" or \"z\""),
                            ))
                        }
                    }
                }
                other => return Err(self.unknown_key(key, other, &UV_KEYS, "uv")),
            }
        }
        let projection = match projection {
            Some(("box", _)) => {
                if axis_span.is_some() {
                    return Err(self.error(axis_span, "a box projection takes no `axis`"));
                }
                Projection::Box
            }
            Some(("planar", _)) => Projection::Planar { axis },
            Some(("cylindrical", _)) => Projection::Cylindrical { axis },
            Some(("surface", _)) => Projection::Surface,
            Some((other, span)) => {
                return Err(self.error(
                    span,
                    format!(
                    "unknown projection `{other}`, expected \"box\", \"planar\" or \"cylindrical\""
                ),
                ))
            }
            None => return Err(self.error(value.span.clone(), "`uv` needs a `projection`")),
        };
        Ok(Some(UvMapping { projection, size }))
    }

    /// `color = { hsv = [h, s, v] }` or `{ rgb = [r, g, b] }`: each
    /// channel a number or an expression over face properties.
    fn color_spec(&self, look: &mut Look, value: &Spanned<ArgValue>) -> Result<u32, RuleError> {
        let expected = "{ hsv = [H, S, V] } or { rgb = [R, G, B] }, each a number or an expression over face properties";
        let bad = || self.error(value.span.clone(), format!("expected {expected}"));
        let ArgValue::Table(args) = &value.value else {
            return Err(bad());
        };
        let [(key, channels)] = args.0.as_slice() else {
            return Err(bad());
        };
        let hsv = match key.value.as_str() {
            "hsv" => true,
            "rgb" => false,
            other => return Err(self.unknown_key(key, other, &["hsv", "rgb"], "color")),
        };
        let ArgValue::List(items) = &channels.value else {
            return Err(bad());
        };
        if items.len() != 3 {
            return Err(self.error(
                channels.span.clone(),
                format!("a colour has 3 channels, not {}", items.len()),
            ));
        }
        let mut compiled = Vec::with_capacity(3);
        for item in items {
            let text = match &item.value {
                ArgValue::Number(x) => format!("{x}"),
                ArgValue::Text(t) => t.clone(),
                other => {
                    return Err(self.error(
                        item.span.clone(),
                        format!(
                            "invalid type: {}, expected a number or an expression",
                            other.describe()
                        ),
                    ))
                }
            };
            let written = Spanned {
                value: text,
                span: item.span.clone(),
            };
            compiled.push(self.condition(crate::kernel::Domain::Face, &written)?);
        }
        let channels: [crate::rules::program::Condition; 3] =
            compiled.try_into().expect("three channels");
        look.colors
            .push(crate::rules::program::ColorSpec { hsv, channels });
        Ok(look.colors.len() as u32 - 1)
    }

    fn unknown_key(
        &self,
        key: &Spanned<String>,
        written: &str,
        keys: &[&str],
        of: &str,
    ) -> RuleError {
        let listed: Vec<String> = keys.iter().map(|k| format!("`{k}`")).collect();
        let e = self.error(
            key.span.clone(),
            format!(
                "unknown field `{written}` of {of}, expected one of {}",
                listed.join(", ")
            ),
        );
        match closest_in(written, keys) {
            Some(k) => e.with_help(format!("did you mean `{}`?", keys[k])),
            None => e,
        }
    }
}
