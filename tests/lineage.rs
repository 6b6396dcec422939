//! Lineage-keyed random streams (issue 33): a step's stream is named by
//! its name or its content, a primitive's draws by its lineage, so
//! inserting or editing a step re-rolls only that step and what descends
//! from it.

mod common;
use common::{grow, toml};

use graftal::grammar::lineage::LINEAGE;
use graftal::grammar::RunOutput;
use graftal::kernel::Domain;

/// A grid; a hair from every node (unnamed, drawing its length and turn);
/// a bent tip on every hair (unnamed, drawing its pitch); and, apart, a
/// fan of every face with a drawn lift (named `fan`).
const BASE: &str = r#"
[start]
grid = { segments = [4, 4], size = [4, 4] }

[[step]]
on = "verts"
select = "faces > 0"
create_edge = { heading = [0, 0, 1], length = 2, vary_length = 0.5, vary_turn = 40, vary_pitch = 20 }

[[step]]
on = "verts"
select = "faces == 0 && out_edges == 0"
create_edge = { relative = true, length = 0.5, vary_pitch = 30, vary_turn = 30 }

[[step]]
name = "fan"
split_face = { length = 0.1, vary_length = 0.05 }
"#;

/// The positions of every vertex, as bit patterns, sorted: a picture of
/// the model that ignores ids.
fn points(out: &RunOutput) -> Vec<[u64; 3]> {
    let mut p: Vec<[u64; 3]> = out
        .mesh
        .vert_ids()
        .map(|v| out.mesh.position(v).to_array().map(f64::to_bits))
        .collect();
    p.sort_unstable();
    p
}

fn above(out: &RunOutput, z: f64) -> Vec<[u64; 3]> {
    points(out)
        .into_iter()
        .filter(|p| f64::from_bits(p[2]) > z)
        .collect()
}

#[test]
fn inserting_a_step_rerolls_nothing_else() {
    let base = grow(BASE);
    // A step inserted first that makes primitives (shifting every later
    // id) and draws from its own stream.
    let inserted = BASE.replacen(
        "[[step]]",
        "[[step]]\nvertex = { at = [9, 9, 9] }\n\n[[step]]\non = \"verts\"\nselect = \"pos.x > 8\"\ncreate_edge = { heading = [1, 0, 0], vary_length = 0.3 }\n\n[[step]]",
        1,
    );
    let more = grow(&inserted);
    let (a, b) = (points(&base), points(&more));
    // The new node, its edge's end and the tip grown on it.
    assert!(b.len() == a.len() + 3, "{} vs {}", a.len(), b.len());
    // Every point of the base model is there, bit for bit: hairs, tips and
    // fan centres kept their draws although their ids and their steps'
    // positions moved.
    let missing: Vec<_> = a.iter().filter(|p| b.binary_search(p).is_err()).collect();
    assert!(missing.is_empty(), "{} points re-rolled", missing.len());
}

#[test]
fn editing_a_step_rerolls_it_and_its_descendants_only() {
    let base = grow(BASE);
    let edited = grow(&BASE.replace("vary_length = 0.5", "vary_length = 0.6"));
    // The hairs (z > 0.2) moved: their step changed, and so did the tips
    // grown from them.
    let (a, b) = (above(&base, 0.35), above(&edited, 0.35));
    assert_eq!(a.len(), b.len());
    let kept = a.iter().filter(|p| b.binary_search(p).is_ok()).count();
    assert!(
        kept < a.len() / 10,
        "{kept} of {} hair points kept",
        a.len()
    );
    // The fan does not descend from the hairs: its centres (the only
    // points lifted above the grid by less than 0.35) are the same bits.
    let fan = |o: &RunOutput| -> Vec<[u64; 3]> {
        points(o)
            .into_iter()
            .filter(|p| (1e-9..0.35).contains(&f64::from_bits(p[2])))
            .collect()
    };
    assert_eq!(fan(&base).len(), 16);
    assert_eq!(fan(&base), fan(&edited));
}

#[test]
fn unnamed_steps_are_keyed_by_content_and_twins_apart() {
    let p = toml(BASE);
    let q = toml(&BASE.replace("[start]", "# a comment moves every byte\n[start]"));
    let keys =
        |p: &graftal::rules::Program| -> Vec<u64> { p.steps.iter().map(|s| s.key).collect() };
    assert_eq!(keys(&p), keys(&q));
    // Two identical unnamed steps draw from two streams.
    let first = BASE.find("[[step]]").unwrap();
    let second = first + 1 + BASE[first + 1..].find("[[step]]").unwrap();
    let hair = &BASE[first..second];
    let twice = BASE.replacen(hair, &format!("{hair}{hair}"), 1);
    let t = toml(&twice);
    assert_eq!(t.steps.len(), p.steps.len() + 1);
    assert_ne!(t.steps[1].key, t.steps[2].key);
    // The first twin keeps the key the lone step had.
    assert_eq!(t.steps[1].key, p.steps[1].key);
    // `repeat` names each copy; raising it keeps the earlier copies' keys.
    let rep =
        |n: u32| toml(&BASE.replace("name = \"fan\"", &format!("name = \"fan\"\nrepeat = {n}")));
    let (two, three) = (rep(2), rep(3));
    assert_eq!(keys(&two)[..], keys(&three)[..keys(&two).len()]);
}

#[test]
fn programs_that_draw_nothing_keep_no_lineage() {
    let plain = grow(
        "[start]\ngrid = { segments = [3, 3] }\n[[step]]\nextrude_faces = { offset = [0, 0, 1] }\n",
    );
    for domain in [Domain::Vert, Domain::Edge, Domain::Face] {
        assert!(plain.mesh.attributes().layer(LINEAGE, domain).is_none());
    }
    let drawing = grow(BASE);
    assert!(drawing
        .mesh
        .attributes()
        .layer(LINEAGE, Domain::Vert)
        .is_some());
}
