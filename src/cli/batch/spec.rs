//! What `graftal run` is asked for, as typed: seed sets, grid axes,
//! shards (fixed or from the scheduler's environment) and output path
//! templates. Parsing only; [`super::resolve`] turns these into variants.

use crate::cli::Failure;

/// More variants than this in one batch is surely a typo'd range.
pub const MAX_VARIANTS: u64 = 10_000_000;

/// `--seeds`: comma-separated items, each `N`, `A..B` (B excluded) or
/// `A..=B`.
#[derive(Clone, Debug)]
pub struct SeedSet {
    /// Normalized text (what the manifest records).
    pub text: String,
    pub seeds: Vec<u64>,
}

impl SeedSet {
    pub fn parse(text: &str) -> Result<SeedSet, String> {
        let number = |s: &str| -> Result<u64, String> {
            s.trim().parse::<u64>().map_err(|_| {
                format!(
                    "`{}` is not a seed (a whole number from 0 to 2^64 - 1)",
                    s.trim()
                )
            })
        };
        let mut seeds = Vec::new();
        let mut items = Vec::new();
        for item in text.split(',') {
            let item = item.trim();
            if item.is_empty() {
                return Err(format!(
                    "`{text}`: empty item (expected N, A..B or A..=B, comma-separated)"
                ));
            }
            // Inclusive bounds, so that seed 2^64 - 1 is a seed like any other.
            let (first, last) = if let Some((a, b)) = item.split_once("..=") {
                (number(a)?, Some(number(b)?))
            } else if let Some((a, b)) = item.split_once("..") {
                (number(a)?, number(b)?.checked_sub(1))
            } else {
                let n = number(item)?;
                (n, Some(n))
            };
            let Some(last) = last.filter(|&last| first <= last) else {
                return Err(format!("the range `{item}` is empty"));
            };
            if (seeds.len() as u64)
                .saturating_add(last - first)
                .saturating_add(1)
                > MAX_VARIANTS
            {
                return Err(format!(
                    "`{text}` names more than {MAX_VARIANTS} seeds; split the batch"
                ));
            }
            seeds.extend(first..=last);
            items.push(item.replace(' ', ""));
        }
        let mut sorted = seeds.clone();
        sorted.sort_unstable();
        if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
            return Err(format!("seed {} is listed twice in `{text}`", w[0]));
        }
        Ok(SeedSet {
            text: items.join(","),
            seeds,
        })
    }
}

/// `--grid name=v1,v2,…`: one axis of the parameter grid.
#[derive(Clone, Debug)]
pub struct GridAxis {
    pub name: String,
    pub values: Vec<String>,
}

impl GridAxis {
    pub fn parse(text: &str) -> Result<GridAxis, String> {
        let (name, values) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}` is not of the form name=v1,v2,..."))?;
        let name = name.trim();
        let first = name.chars().next();
        if !first.is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
            || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        {
            return Err(format!("`{name}` is not a parameter name"));
        }
        let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
        if values.iter().any(String::is_empty) {
            return Err(format!("`{text}`: empty value in the list"));
        }
        Ok(GridAxis {
            name: name.to_string(),
            values,
        })
    }
}

/// `--shard i/n`: the variants whose index is `i` modulo `n` (0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl Shard {
    pub fn parse(text: &str) -> Result<Shard, String> {
        let (i, n) = text
            .split_once('/')
            .ok_or_else(|| format!("`{text}` is not of the form i/n (e.g. 0/4)"))?;
        let (index, count) = (whole(text, i)?, whole(text, n)?);
        Shard::new(index, count).map_err(|m| format!("`{text}`: {m}"))
    }

    fn new(index: usize, count: usize) -> Result<Shard, String> {
        if count == 0 {
            return Err("the shard count must be at least 1".into());
        }
        if index >= count {
            return Err(format!(
                "shard {index} of {count}: shards are numbered from 0 to {} (0-based)",
                count - 1
            ));
        }
        Ok(Shard { index, count })
    }
}

fn whole(text: &str, s: &str) -> Result<usize, String> {
    s.trim()
        .parse::<usize>()
        .map_err(|_| format!("`{text}`: `{s}` is not a whole number"))
}

/// `--shard` as written: `i/n`, or `auto` / `auto/n` to take the shard
/// from the scheduler's environment ([`ShardArg::resolve`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShardArg {
    Fixed(Shard),
    /// `auto/n` gives the count Kubernetes does not export (and checks
    /// the one Slurm does).
    Auto {
        count: Option<usize>,
    },
}

/// The variables `--shard auto` reads, in the order it reports them.
pub const SHARD_VARIABLES: &[&str] = &[
    "SLURM_ARRAY_TASK_ID",
    "SLURM_ARRAY_TASK_MIN",
    "SLURM_ARRAY_TASK_STEP",
    "SLURM_ARRAY_TASK_COUNT",
    "JOB_COMPLETION_INDEX",
    "GRAFTAL_SHARD",
];

impl ShardArg {
    pub fn parse(text: &str) -> Result<ShardArg, String> {
        match text.trim() {
            "auto" => Ok(ShardArg::Auto { count: None }),
            t => match t.strip_prefix("auto/") {
                Some(n) => {
                    let count = whole(text, n)?;
                    if count == 0 {
                        return Err(format!("`{text}`: the shard count must be at least 1"));
                    }
                    Ok(ShardArg::Auto { count: Some(count) })
                }
                None => Shard::parse(text).map(ShardArg::Fixed),
            },
        }
    }

    /// The shard to run. `auto` reads, through `var`, a Slurm job array
    /// (index = (`SLURM_ARRAY_TASK_ID` − `SLURM_ARRAY_TASK_MIN`) /
    /// `SLURM_ARRAY_TASK_STEP`, count `SLURM_ARRAY_TASK_COUNT`), a
    /// Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`, the count from
    /// `auto/n`) and `GRAFTAL_SHARD=i/n`. Every source that is set must
    /// agree; none set is an error naming what was looked for.
    pub fn resolve(self, var: &dyn Fn(&str) -> Option<String>) -> Result<Shard, String> {
        let count = match self {
            ShardArg::Fixed(shard) => return Ok(shard),
            ShardArg::Auto { count } => count,
        };
        let read = |name: &str| -> Result<Option<usize>, String> {
            match var(name) {
                None => Ok(None),
                Some(v) if v.trim().is_empty() => Ok(None),
                Some(v) => v
                    .trim()
                    .parse::<usize>()
                    .map(Some)
                    .map_err(|_| format!("--shard auto: {name}=`{v}` is not a whole number")),
            }
        };
        // (where it came from, index, count if the source knows it)
        let mut found: Vec<(String, usize, Option<usize>)> = Vec::new();
        if let Some(id) = read("SLURM_ARRAY_TASK_ID")? {
            let missing = |name: &str| {
                format!("--shard auto: SLURM_ARRAY_TASK_ID is set but {name} is not (is this a Slurm job array?)")
            };
            let min =
                read("SLURM_ARRAY_TASK_MIN")?.ok_or_else(|| missing("SLURM_ARRAY_TASK_MIN"))?;
            let total =
                read("SLURM_ARRAY_TASK_COUNT")?.ok_or_else(|| missing("SLURM_ARRAY_TASK_COUNT"))?;
            let step = read("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
            let offset = id.checked_sub(min).filter(|o| o % step == 0).ok_or_else(|| {
                format!("--shard auto: SLURM_ARRAY_TASK_ID={id} is not SLURM_ARRAY_TASK_MIN={min} plus a multiple of SLURM_ARRAY_TASK_STEP={step}")
            })?;
            found.push((
                format!("Slurm (SLURM_ARRAY_TASK_ID={id}, SLURM_ARRAY_TASK_MIN={min}, SLURM_ARRAY_TASK_COUNT={total})"),
                offset / step,
                Some(total),
            ));
        }
        if let Some(index) = read("JOB_COMPLETION_INDEX")? {
            found.push((
                format!("Kubernetes (JOB_COMPLETION_INDEX={index})"),
                index,
                None,
            ));
        }
        if let Some(text) = var("GRAFTAL_SHARD").filter(|t| !t.trim().is_empty()) {
            let shard =
                Shard::parse(&text).map_err(|m| format!("--shard auto: GRAFTAL_SHARD: {m}"))?;
            found.push((
                format!("GRAFTAL_SHARD={}", text.trim()),
                shard.index,
                Some(shard.count),
            ));
        }
        let Some((first, index, _)) = found.first().cloned() else {
            return Err(format!(
                "--shard auto: no shard in the environment; looked for {} (a Slurm job array, a Kubernetes Indexed Job, or GRAFTAL_SHARD=i/n)",
                SHARD_VARIABLES.join(", ")
            ));
        };
        let counts = count.iter().map(|&n| ("--shard auto/N".to_string(), n));
        let counts: Vec<(String, usize)> = counts
            .chain(
                found
                    .iter()
                    .filter_map(|(w, _, n)| n.map(|n| (w.clone(), n))),
            )
            .collect();
        let Some((_, total)) = counts.first().cloned() else {
            return Err(format!(
                "--shard auto: {first} gives the shard index but not the count; Kubernetes does not export it: write --shard auto/N with the Job's `completions`"
            ));
        };
        for (what, n) in &counts {
            if *n != total {
                return Err(format!(
                    "--shard auto: the shard counts disagree: {} says {total}, {what} says {n}",
                    counts[0].0
                ));
            }
        }
        for (what, i, _) in &found {
            if *i != index {
                return Err(format!(
                    "--shard auto: the shard indices disagree: {first} gives {index}, {what} gives {i}"
                ));
            }
        }
        Shard::new(index, total).map_err(|m| format!("--shard auto: {first}: {m}"))
    }
}

/// An output path template: literal text and `{field}` or `{field:0N}`
/// (zero-padded to N digits; seeds and indices only); `{{` and `}}` are
/// literal braces.
#[derive(Clone, Debug)]
pub struct Template {
    text: String,
    pieces: Vec<Piece>,
}

#[derive(Clone, Debug)]
enum Piece {
    Text(String),
    Field { name: String, width: Option<usize> },
}

/// A value a template field takes.
pub(super) enum FieldValue<'a> {
    Int(u64),
    Float(f64),
    Text(&'a str),
}

impl Template {
    pub fn parse(text: &str) -> Result<Template, String> {
        let mut pieces = Vec::new();
        let mut literal = String::new();
        let mut chars = text.chars().peekable();
        while let Some(c) = chars.next() {
            match c {
                '{' if chars.peek() == Some(&'{') => {
                    chars.next();
                    literal.push('{');
                }
                '}' if chars.peek() == Some(&'}') => {
                    chars.next();
                    literal.push('}');
                }
                '{' => {
                    let mut spec = String::new();
                    loop {
                        match chars.next() {
                            Some('}') => break,
                            Some(c) => spec.push(c),
                            None => return Err(format!("`{text}`: `{{` without a closing `}}`")),
                        }
                    }
                    let (name, width) = match spec.split_once(':') {
                        None => (spec.as_str(), None),
                        Some((name, w)) => {
                            let digits = w.strip_prefix('0').unwrap_or(w);
                            let width = digits.parse::<usize>().ok().filter(|&w| w <= 20);
                            match width {
                                Some(width) if w.starts_with('0') => (name, Some(width)),
                                _ => {
                                    return Err(format!(
                                        "`{text}`: `{{{spec}}}`: the only format is `:0N`, zero-padding to N digits (N up to 20)"
                                    ))
                                }
                            }
                        }
                    };
                    if name.is_empty() {
                        return Err(format!("`{text}`: empty field `{{{spec}}}`"));
                    }
                    if !literal.is_empty() {
                        pieces.push(Piece::Text(std::mem::take(&mut literal)));
                    }
                    pieces.push(Piece::Field {
                        name: name.to_string(),
                        width,
                    });
                }
                '}' => {
                    return Err(format!(
                        "`{text}`: `}}` without an opening `{{` (write `}}}}` for a brace)"
                    ))
                }
                c => literal.push(c),
            }
        }
        if !literal.is_empty() {
            pieces.push(Piece::Text(literal));
        }
        Ok(Template {
            text: text.to_string(),
            pieces,
        })
    }

    pub fn text(&self) -> &str {
        &self.text
    }

    /// The literal text before the first field.
    pub(super) fn fixed_prefix(&self) -> &str {
        match self.pieces.first() {
            Some(Piece::Text(t)) => t,
            _ => "",
        }
    }

    /// Checks every field against the names a variant can fill in.
    pub(super) fn check_fields(&self, what: &str, params: &[String]) -> Result<(), Failure> {
        for piece in &self.pieces {
            let Piece::Field { name, width } = piece else {
                continue;
            };
            let integer = matches!(name.as_str(), "seed" | "index");
            let known = integer || name == "name" || params.iter().any(|p| p == name);
            if !known {
                let mut fields = vec!["name".to_string(), "seed".into(), "index".into()];
                fields.extend(params.iter().cloned());
                return Err(Failure::Input(format!(
                    "{what} `{}`: unknown field `{{{name}}}`; fields are {}",
                    self.text,
                    fields.join(", ")
                )));
            }
            if width.is_some() && !integer {
                return Err(Failure::Input(format!(
                    "{what} `{}`: `{{{name}}}` cannot be zero-padded (only seed and index)",
                    self.text
                )));
            }
        }
        Ok(())
    }

    pub(super) fn render<'a>(&self, field: impl Fn(&str) -> FieldValue<'a>) -> String {
        let mut out = String::new();
        for piece in &self.pieces {
            match piece {
                Piece::Text(t) => out.push_str(t),
                Piece::Field { name, width } => match (field(name), width) {
                    (FieldValue::Int(n), Some(w)) => out.push_str(&format!("{n:0w$}")),
                    (FieldValue::Int(n), None) => out.push_str(&n.to_string()),
                    (FieldValue::Float(x), _) => out.push_str(&x.to_string()),
                    (FieldValue::Text(t), _) => out.push_str(t),
                },
            }
        }
        out
    }
}
