//! Rule-file tooling and shell integration: `schema`, `lint`, `explain`,
//! `completions`, `man`. See docs/tooling.md.

use std::collections::HashSet;
use std::io::Write;
use std::path::{Path, PathBuf};

use clap::CommandFactory;
use serde::Serialize;

use super::{Cli, Failure};
use crate::grammar::{self, RunOptions, StepStats};
use crate::rules::lint::{self, Severity};
use crate::rules::program::{Op, Step};
use crate::rules::{schema, Override, Program};

/// `graftal schema`: the JSON Schema of rule files on standard output.
pub fn schema() -> Result<(), Failure> {
    super::write_stdout(schema::schema_text().as_bytes())
}

/// `graftal lint`: findings on standard error, one summary line per file.
/// Exit 0 when every file is clean, 1 with warnings, 2 when a file does not
/// parse or compile.
pub fn lint(files: &[PathBuf], overrides: &[Override], allow: &[String]) -> Result<(), Failure> {
    let mut broken = 0;
    let mut warnings = 0;
    let mut warned_files = 0;
    let mut err = std::io::stderr().lock();
    for path in files {
        let findings = match super::files::read_rules(path)
            .and_then(|file| lint::lint_source(&file, overrides, &super::files::base_dir(path)))
        {
            Ok(f) => f,
            Err(e) => {
                drop(err);
                Failure::from(e).report();
                err = std::io::stderr().lock();
                let _ = writeln!(err, "{}: does not compile", path.display());
                broken += 1;
                continue;
            }
        };
        let shown: Vec<_> = findings
            .into_iter()
            .filter(|f| !allow.iter().any(|a| a == f.code))
            .collect();
        for f in &shown {
            let _ = writeln!(err, "{}", f.headline());
            if let Some(help) = &f.help {
                let _ = writeln!(err, "  = help: {help}");
            }
        }
        let errors = shown
            .iter()
            .filter(|f| f.severity == Severity::Error)
            .count();
        let n = shown.len() - errors;
        if errors > 0 {
            broken += 1;
            let _ = writeln!(
                err,
                "{}: {errors} error{} (does not compile)",
                path.display(),
                plural(errors)
            );
        } else if n > 0 {
            warnings += n;
            warned_files += 1;
            let _ = writeln!(err, "{}: {n} warning{}", path.display(), plural(n));
        } else {
            let _ = writeln!(err, "{}: ok", path.display());
        }
    }
    if broken > 0 {
        return Err(Failure::Input(format!(
            "{broken} of {} rule file{} do{} not compile",
            files.len(),
            plural(files.len()),
            if broken == 1 { "es" } else { "" }
        )));
    }
    if warnings > 0 {
        return Err(Failure::Runtime(format!(
            "lint: {warnings} warning{} in {warned_files} of {} file{}",
            plural(warnings),
            files.len(),
            plural(files.len())
        )));
    }
    Ok(())
}

fn plural(n: usize) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// `graftal completions SHELL`.
pub fn completions(shell: clap_complete::Shell) -> Result<(), Failure> {
    let mut cmd = Cli::command();
    let mut script = Vec::new();
    clap_complete::generate(shell, &mut cmd, "graftal", &mut script);
    super::write_stdout(&script)
}

/// `graftal man [--dir DIR]`: the man page (roff) on standard output, or
/// `graftal.1` and one `graftal-COMMAND.1` per subcommand written to DIR.
pub fn man(dir: Option<&Path>) -> Result<(), Failure> {
    let cmd = Cli::command();
    match dir {
        None => {
            let mut buffer = Vec::new();
            clap_mangen::Man::new(cmd)
                .render(&mut buffer)
                .map_err(|e| Failure::Runtime(format!("cannot render the man page: {e}")))?;
            super::write_stdout(&buffer)
        }
        Some(dir) => {
            if !super::files::is_dir(dir) {
                return Err(Failure::Input(format!(
                    "{}: not a directory",
                    dir.display()
                )));
            }
            // One page per command (`graftal-run.1`, …), as clap_mangen's
            // `generate_to` names them, written all or none.
            fn pages(cmd: clap::Command, out: &mut Vec<(String, Vec<u8>)>) -> std::io::Result<()> {
                for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()).cloned() {
                    pages(sub, out)?;
                }
                let man = clap_mangen::Man::new(cmd);
                let mut buffer = Vec::new();
                man.render(&mut buffer)?;
                out.push((man.get_filename(), buffer));
                Ok(())
            }
            let mut cmd = cmd.disable_help_subcommand(true);
            cmd.build();
            let mut rendered = Vec::new();
            pages(cmd, &mut rendered)
                .map_err(|e| Failure::Runtime(format!("cannot render the man pages: {e}")))?;
            let mut staged = super::files::Staged::new();
            for (name, bytes) in &rendered {
                let path = dir.join(name);
                staged.stage(&path, bytes).map_err(|e| {
                    Failure::Runtime(format!("cannot write {}: {e}", path.display()))
                })?;
            }
            staged.commit().map_err(|(path, e)| {
                Failure::Runtime(format!("cannot write {}: {e}", path.display()))
            })?;
            eprintln!("wrote {} man pages to {}", rendered.len(), dir.display());
            Ok(())
        }
    }
}

/// One step's line in `graftal explain`.
#[derive(Serialize)]
struct ExplainStep<'a> {
    name: &'a str,
    op: &'static str,
    /// What the operator does (the registry's summary).
    summary: &'static str,
    location: &'a str,
    /// The step's generation (its products' `age`): program order, compound
    /// contents included.
    generation: u32,
    /// Compound nesting: 0 at top level.
    depth: usize,
    /// Whether the step ran at all.
    ran: bool,
    runs: usize,
    candidates: usize,
    matched: usize,
    applied: usize,
    condition_false: usize,
    skipped_by_probability: usize,
    shared: usize,
    rejected_by_intersection: usize,
    cancelled: usize,
    /// Of `cancelled`, compound applications cancelled by a step that is
    /// not itself a compound call.
    cancelled_compounds: usize,
    merged: usize,
    created_vertices: usize,
    created_edges: usize,
    created_faces: usize,
    /// Why a step that did not run did not (text only).
    #[serde(skip_serializing_if = "Option::is_none")]
    note: Option<String>,
}

#[derive(Serialize)]
struct ExplainJson<'a> {
    rules: &'a str,
    rule_hash: String,
    seed: u64,
    params: Vec<(&'a str, f64)>,
    vertices: usize,
    edges: usize,
    faces: usize,
    steps: Vec<ExplainStep<'a>>,
}

/// `graftal explain`: runs the rules and tells, per step, what it matched,
/// what it applied to and why the rest was left.
pub fn explain(
    rules_path: &Path,
    seed: Option<u64>,
    overrides: &[Override],
    json: bool,
    max_primitives: usize,
    input: &super::InputArgs,
) -> Result<(), Failure> {
    let program = super::files::compile_rules(rules_path, overrides)?;
    let inputs = super::files::load_inputs(&program, input.policy())?;
    let options = RunOptions {
        seed,
        max_elements: max_primitives,
        inputs: inputs.meshes,
        ..RunOptions::default()
    };
    let result = grammar::run(&program, &options)
        .map_err(|e| Failure::Limit(super::run_exit_code(e.kind), e.to_string()))?;
    let report = result.mesh.report();
    let steps = explain_steps(&program, &result.steps);
    let doc = ExplainJson {
        rules: &program.file,
        rule_hash: format!("{:016x}", program.rule_hash),
        seed: result.seed,
        params: result
            .params
            .iter()
            .map(|(n, v)| (n.as_str(), *v))
            .collect(),
        vertices: report.verts,
        edges: report.edges,
        faces: report.faces,
        steps,
    };
    let text = if json {
        format!(
            "{}\n",
            serde_json::to_string_pretty(&doc).expect("explain serializes")
        )
    } else {
        explain_text(&doc)
    };
    super::write_stdout(text.as_bytes())
}

/// Program steps in running order (a compound's steps after its first
/// call, one level deeper), matched with the stats of those that ran.
fn explain_steps<'a>(program: &'a Program, stats: &'a [Box<StepStats>]) -> Vec<ExplainStep<'a>> {
    // Every step by uid, with its depth and whether it is inside a compound.
    let mut ordered: Vec<(&'a Step, usize, Option<String>)> = Vec::new();
    let mut seen: HashSet<usize> = HashSet::new();
    fn walk<'a>(
        program: &'a Program,
        steps: &'a [Step],
        depth: usize,
        compound: Option<&'a str>,
        seen: &mut HashSet<usize>,
        out: &mut Vec<(&'a Step, usize, Option<String>)>,
    ) {
        for step in steps {
            out.push((
                step,
                depth,
                compound.map(|c| format!("compound `{c}` was applied to no primitive")),
            ));
            if let Op::Compound { index, .. } = &step.op {
                if seen.insert(*index) {
                    let c = &program.compounds[*index];
                    walk(program, &c.steps, depth + 1, Some(&c.name), seen, out);
                }
            }
        }
    }
    walk(program, &program.steps, 0, None, &mut seen, &mut ordered);
    // Stats come in uid order, one per step that ran.
    let mut by_uid: Vec<(&Step, usize)> = ordered.iter().map(|(s, d, _)| (*s, *d)).collect();
    by_uid.sort_by_key(|(s, _)| s.uid);
    let mut ran: Vec<Option<&StepStats>> = vec![None; program.step_count];
    let mut next = stats.iter().peekable();
    for (step, _) in &by_uid {
        if next.peek().is_some_and(|s| s.name == step.name) {
            ran[step.uid as usize] = next.next().map(|s| &**s);
        }
    }
    ordered
        .into_iter()
        .map(|(step, depth, in_compound)| {
            let s = ran.get(step.uid as usize).copied().flatten();
            let get = |f: fn(&StepStats) -> usize| s.map_or(0, f);
            let note = match s {
                Some(_) => None,
                None => Some(in_compound.unwrap_or_else(|| {
                    if step.rule_instances.is_empty() {
                        "the run ended before it".to_owned()
                    } else {
                        "its rule application was cancelled before it".to_owned()
                    }
                })),
            };
            ExplainStep {
                name: &step.name,
                op: step.op.name(),
                summary: crate::rules::operators::find(step.op.name()).map_or(
                    "a compound command: its steps in the scope of each matched primitive",
                    |d| d.summary,
                ),
                location: &step.location,
                generation: step.uid + 1,
                depth,
                ran: s.is_some(),
                runs: get(|s| s.runs),
                candidates: get(|s| s.candidates),
                matched: get(|s| s.matched),
                applied: get(|s| s.applied),
                condition_false: get(|s| s.candidates.saturating_sub(s.matched)),
                skipped_by_probability: get(|s| s.skipped),
                shared: get(|s| s.shared),
                rejected_by_intersection: get(|s| s.rejected),
                cancelled: get(|s| s.cancelled),
                cancelled_compounds: get(|s| s.cancelled_compounds),
                merged: get(|s| s.merged),
                created_vertices: get(|s| s.created.verts),
                created_edges: get(|s| s.created.edges),
                created_faces: get(|s| s.created.faces),
                note,
            }
        })
        .collect()
}

fn count(n: usize, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

fn explain_text(doc: &ExplainJson) -> String {
    let mut s = String::new();
    s += &format!(
        "{} (seed {}): {}, {}, {}\n",
        doc.rules,
        doc.seed,
        count(doc.vertices, "vertex", "vertices"),
        count(doc.edges, "edge", "edges"),
        count(doc.faces, "face", "faces"),
    );
    if !doc.params.is_empty() {
        let params: Vec<String> = doc
            .params
            .iter()
            .map(|(n, v)| format!("{n} = {v}"))
            .collect();
        s += &format!("parameters: {}\n", params.join(", "));
    }
    for step in &doc.steps {
        let indent = "  ".repeat(step.depth);
        s += &format!(
            "\n{indent}{} ({}) at {}\n",
            step.name, step.op, step.location
        );
        let indent = format!("{indent}  ");
        s += &format!("{indent}{}\n", step.summary);
        if !step.ran {
            s += &format!(
                "{indent}did not run: {}\n",
                step.note.as_deref().unwrap_or("")
            );
            continue;
        }
        // Transforms, `merge`, `region_*` and `edit_node` report what they
        // moved or selected (what `from` sees), not new elements.
        let verb = match step.op {
            "translate" | "rotate" | "scale" | "merge" | "region_extend" | "region_reduce"
            | "edit_node" => "moved or selected",
            _ => "created",
        };
        let made = |s: &ExplainStep| {
            let mut parts = Vec::new();
            for (n, one, many) in [
                (s.created_vertices, "vertex", "vertices"),
                (s.created_edges, "edge", "edges"),
                (s.created_faces, "face", "faces"),
            ] {
                if n > 0 {
                    parts.push(count(n, one, many));
                }
            }
            if parts.is_empty() {
                "nothing".to_owned()
            } else {
                parts.join(", ")
            }
        };
        let runs = if step.runs > 1 {
            format!(" (over {} runs)", step.runs)
        } else {
            String::new()
        };
        let creates = step.candidates == 0 && step.matched == 0 && step.applied == 0;
        if creates
            && step.runs > 0
            && step.created_vertices + step.created_edges + step.created_faces > 0
        {
            s += &format!("{indent}{verb} {}{runs}\n", made(step));
            continue;
        }
        s += &format!(
            "{indent}{}, {} matched, {} applied{runs}; {verb} {}\n",
            count(step.candidates, "candidate", "candidates"),
            step.matched,
            step.applied,
            made(step)
        );
        if step.condition_false > 0 {
            s += &format!(
                "{indent}not matched: {} (condition false)\n",
                step.condition_false
            );
        }
        let mut left = Vec::new();
        if step.skipped_by_probability > 0 {
            left.push(format!(
                "{} skipped by probability",
                step.skipped_by_probability
            ));
        }
        if step.shared > 0 {
            left.push(format!(
                "{} shared (applied from another scope already; products reused)",
                step.shared
            ));
        }
        if step.rejected_by_intersection > 0 {
            left.push(format!(
                "{} rejected by intersection",
                step.rejected_by_intersection
            ));
        }
        if !left.is_empty() {
            s += &format!("{indent}matched, not applied: {}\n", left.join(", "));
        }
        if step.cancelled > 0 {
            let (compounds, rules) = if step.op == "compound" {
                (step.cancelled, 0)
            } else {
                (
                    step.cancelled_compounds,
                    step.cancelled - step.cancelled_compounds,
                )
            };
            if compounds > 0 {
                s += &format!(
                    "{indent}cancelled: {compounds} compound applications rolled back (cancel_compound)\n"
                );
            }
            if rules > 0 {
                s += &format!(
                    "{indent}cancelled: {rules} rule applications rolled back (cancel_rule)\n"
                );
            }
        }
        if step.merged > 0 {
            s += &format!(
                "{indent}merged: {} into coinciding nodes\n",
                count(step.merged, "node", "nodes")
            );
        }
        if step.matched == 0 && step.candidates == 0 && step.runs > 0 {
            s += &format!(
                "{indent}no candidates: nothing of its kind was there (or `from` made nothing)\n"
            );
        }
    }
    s
}
