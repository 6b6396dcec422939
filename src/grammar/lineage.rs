//! Lineage keys: what a primitive's random draws are keyed by (issue 33).
//!
//! Keying draws by arena id made them follow application order: a step
//! inserted before another shifted the ids of everything after it and
//! re-rolled unrelated primitives. Instead every primitive carries a
//! 64-bit key derived, when a step makes it, from
//!
//! * the key of the step that made it (its name or content, `step_key`),
//! * its parent's key: for a G³ command the primitive the command was
//!   applied to; for an operator the element it was derived from (the
//!   kernel's operators copy attributes, and so this key, from it);
//!   `0` for what comes from nothing (a start shape, a mesh import),
//! * its kind and its index among the products of that application that
//!   share the parent (in the order the operator lists them).
//!
//! So a primitive's draws change only when the step that made it, or an
//! ancestor's, changes. The keys live in a `Key` attribute layer per
//! domain, kept only by programs that draw per primitive
//! (`Program::draws_per_primitive`): the others pay nothing.

use rustc_hash::FxHashMap;

use crate::kernel::attrs::AttrValue;
use crate::kernel::ops::Selection;
use crate::kernel::{Domain, Mesh};
use crate::rules::random;

/// The attribute layer holding the keys (every domain).
pub const LINEAGE: &str = "lineage";

/// Adds the lineage layers if missing (a whole-mesh operator may have
/// replaced the mesh, and its layers with it).
pub fn ensure_layers(mesh: &mut Mesh) {
    for domain in [Domain::Vert, Domain::Edge, Domain::Face] {
        let _ = mesh.add_layer(LINEAGE, domain, AttrValue::Key(0));
    }
}

/// The key of element `index` of `domain` (0 where none was given).
#[inline]
pub fn key(mesh: &Mesh, domain: Domain, index: usize) -> u64 {
    match mesh.attr(LINEAGE, domain, index) {
        Some(AttrValue::Key(k)) => k,
        _ => 0,
    }
}

/// The key of the `nth` product of kind `domain` that `step` made from
/// `parent` (a hash: no two (step, parent, kind, n) meet by design).
#[inline]
pub fn derive(step: u64, parent: u64, domain: Domain, nth: u64) -> u64 {
    let kind = match domain {
        Domain::Vert => 1,
        Domain::Edge => 2,
        Domain::Face => 3,
    };
    random::draw_u64(step, parent, kind, nth)
}

/// Keys the products of one G³ command application, all children of the
/// primitive it applied to (`parent`, its key read before applying).
pub fn assign_children(mesh: &mut Mesh, step: u64, parent: u64, made: &Selection) {
    let lists: [(Domain, Vec<usize>); 3] = [
        (Domain::Vert, made.verts.iter().map(|v| v.index()).collect()),
        (Domain::Edge, made.edges.iter().map(|e| e.index()).collect()),
        (Domain::Face, made.faces.iter().map(|f| f.index()).collect()),
    ];
    for (domain, ids) in lists {
        for (nth, index) in ids.into_iter().enumerate() {
            let k = derive(step, parent, domain, nth as u64);
            let _ = mesh.set_attr(LINEAGE, domain, index, AttrValue::Key(k));
        }
    }
}

/// Keys the products of an operator: each is the child of the element it
/// was derived from (whose key the operator copied onto it; 0 for what it
/// made from nothing), numbered among the products sharing that parent.
pub fn assign_derived(mesh: &mut Mesh, step: u64, made: &Selection) {
    ensure_layers(mesh);
    let lists: [(Domain, Vec<usize>); 3] = [
        (Domain::Vert, made.verts.iter().map(|v| v.index()).collect()),
        (Domain::Edge, made.edges.iter().map(|e| e.index()).collect()),
        (Domain::Face, made.faces.iter().map(|f| f.index()).collect()),
    ];
    // Looked up only, never iterated: no order leaks into the keys.
    let mut siblings: FxHashMap<(u64, Domain), u64> = FxHashMap::default();
    for (domain, ids) in lists {
        let parents: Vec<u64> = ids.iter().map(|&i| key(mesh, domain, i)).collect();
        for (index, parent) in ids.into_iter().zip(parents) {
            let nth = siblings.entry((parent, domain)).or_insert(0);
            let k = derive(step, parent, domain, *nth);
            *nth += 1;
            let _ = mesh.set_attr(LINEAGE, domain, index, AttrValue::Key(k));
        }
    }
}
