//! The element properties conditions read: one table, read by the
//! compiler (names to slots), the linter (names and ranges), `explain`,
//! the schema and the engine (slots to properties). Adding a property is a
//! row here and an arm in `grammar::properties`.
//!
//! A condition's slots are the parameters, then the properties in the
//! dense order of [`SLOTS`]: slot = parameter count + [`index`].

use crate::kernel::Domain;

pub use super::program::Property;

const V: &[Domain] = &[Domain::Vert];
const E: &[Domain] = &[Domain::Edge];
const F: &[Domain] = &[Domain::Face];
const VE: &[Domain] = &[Domain::Vert, Domain::Edge];
const VF: &[Domain] = &[Domain::Vert, Domain::Face];
const EF: &[Domain] = &[Domain::Edge, Domain::Face];
const ALL: &[Domain] = &[Domain::Vert, Domain::Edge, Domain::Face];

/// What values a property takes (for the linter's interval analysis).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// Any finite number.
    Finite,
    /// At least `min`; `integer` when only whole numbers occur.
    AtLeast { min: f64, integer: bool },
    /// In `[min, max]`.
    Between { min: f64, max: f64 },
    /// In `[0, 1)`: a uniform draw.
    Unit,
}

/// One name a property is read by, for some kinds of element.
#[derive(Clone, Copy, Debug)]
pub struct Row {
    /// As written in a condition: `area`, `pos.x`.
    pub name: &'static str,
    /// The element kinds that have it under this name.
    pub domains: &'static [Domain],
    pub property: Property,
    pub range: Range,
    /// One line for the reference.
    pub doc: &'static str,
}

const COUNT: Range = Range::AtLeast {
    min: 0.0,
    integer: true,
};
const NONNEG: Range = Range::AtLeast {
    min: 0.0,
    integer: false,
};
const UNIT_COMPONENT: Range = Range::Between {
    min: -1.0,
    max: 1.0,
};

macro_rules! rows {
    ($( $name:literal $domains:ident $property:expr, $range:expr, $doc:literal; )*) => {
        &[$( Row { name: $name, domains: $domains, property: $property, range: $range, doc: $doc }, )*]
    };
}

use Property::*;

/// Every property name, canonical names first (a property's first row
/// names it in messages). Aliases follow: `edges` for a face's `sides` and
/// a vertex's `degree`.
pub static ROWS: &[Row] = rows! {
    "id" ALL Id, COUNT, "the element's arena slot (ids are reused lowest first)";
    "random" ALL Random, Range::Unit, "uniform in [0, 1) from the step's stream and the element's lineage";
    "length" E Length, NONNEG, "edge length";
    "area" F Area, NONNEG, "face area";
    "sides" F Sides, Range::AtLeast { min: 3.0, integer: true }, "corners of the face";
    "degree" V Degree, COUNT, "edges at the vertex";
    "faces" VE FaceCount, COUNT, "faces at the vertex or edge";
    "neighbors" F EdgeNeighbors, COUNT, "faces sharing an edge with the face";
    "vert_neighbors" F VertNeighbors, COUNT, "faces sharing a vertex with the face (8 for an interior grid face)";
    "age" ALL Age, COUNT, "the generation that made the element";
    "generation" ALL Generation, Range::AtLeast { min: 1.0, integer: true }, "the generation of the running step";
    "radius" ALL Radius, Range::Finite, "node radius (mean of the nodes for edges and faces)";
    "out_edges" VE OutEdges, COUNT, "edges leaving the node (an edge: its post-node)";
    "in_edges" VE InEdges, COUNT, "edges entering the node (an edge: its pre-node)";
    "neighbors" E EdgeNeighborEdges, COUNT, "other edges sharing a node with the edge";
    "pre.length" VE PreLength, NONNEG, "mean length of the edges entering the node (an edge: its length)";
    "rel.length" E RelativeLength, NONNEG, "length over the scope's initial primitive's size";
    "rel.area" F RelativeArea, NONNEG, "area over the scope's initial face's area";
    "pos.x" V Position(0), Range::Finite, "vertex position";
    "pos.y" V Position(1), Range::Finite, "vertex position";
    "pos.z" V Position(2), Range::Finite, "vertex position";
    "center.x" EF Center(0), Range::Finite, "edge midpoint, mean of a face's vertices";
    "center.y" EF Center(1), Range::Finite, "edge midpoint, mean of a face's vertices";
    "center.z" EF Center(2), Range::Finite, "edge midpoint, mean of a face's vertices";
    "normal.x" VF Normal(0), UNIT_COMPONENT, "unit normal (a vertex: mean of its faces')";
    "normal.y" VF Normal(1), UNIT_COMPONENT, "unit normal (a vertex: mean of its faces')";
    "normal.z" VF Normal(2), UNIT_COMPONENT, "unit normal (a vertex: mean of its faces')";
    "min.x" EF Min(0), Range::Finite, "bounding box corner";
    "min.y" EF Min(1), Range::Finite, "bounding box corner";
    "min.z" EF Min(2), Range::Finite, "bounding box corner";
    "max.x" EF Max(0), Range::Finite, "bounding box corner";
    "max.y" EF Max(1), Range::Finite, "bounding box corner";
    "max.z" EF Max(2), Range::Finite, "bounding box corner";
    "dir.x" E Direction(0), UNIT_COMPONENT, "unit direction, pre-node to post-node";
    "dir.y" E Direction(1), UNIT_COMPONENT, "unit direction, pre-node to post-node";
    "dir.z" E Direction(2), UNIT_COMPONENT, "unit direction, pre-node to post-node";
    "pre.x" E PrePosition(0), Range::Finite, "pre-node position";
    "pre.y" E PrePosition(1), Range::Finite, "pre-node position";
    "pre.z" E PrePosition(2), Range::Finite, "pre-node position";
    "post.x" E PostPosition(0), Range::Finite, "post-node position";
    "post.y" E PostPosition(1), Range::Finite, "post-node position";
    "post.z" E PostPosition(2), Range::Finite, "post-node position";
    "rel.x" ALL Relative(0), Range::Finite, "position in the scope's frame (x, y span [0, 1] over the initial face)";
    "rel.y" ALL Relative(1), Range::Finite, "position in the scope's frame (x, y span [0, 1] over the initial face)";
    "rel.z" ALL Relative(2), Range::Finite, "position in the scope's frame, in units of its size";
    "edges" F Sides, Range::AtLeast { min: 3.0, integer: true }, "same as `sides`";
    "edges" V Degree, COUNT, "same as `degree`";
};

/// The properties in slot order: a condition's slot `params + k` holds
/// `SLOTS[k]`.
pub const SLOTS: [Property; 45] = [
    Id,
    Random,
    Length,
    Area,
    Sides,
    Degree,
    FaceCount,
    EdgeNeighbors,
    VertNeighbors,
    Age,
    Generation,
    Radius,
    OutEdges,
    InEdges,
    EdgeNeighborEdges,
    PreLength,
    RelativeLength,
    RelativeArea,
    Position(0),
    Position(1),
    Position(2),
    Center(0),
    Center(1),
    Center(2),
    Normal(0),
    Normal(1),
    Normal(2),
    Min(0),
    Min(1),
    Min(2),
    Max(0),
    Max(1),
    Max(2),
    Direction(0),
    Direction(1),
    Direction(2),
    PrePosition(0),
    PrePosition(1),
    PrePosition(2),
    PostPosition(0),
    PostPosition(1),
    PostPosition(2),
    Relative(0),
    Relative(1),
    Relative(2),
];

/// Number of property slots after the parameters.
pub const SLOT_COUNT: usize = SLOTS.len();

/// The property in slot `k` past the parameters.
#[inline]
pub fn at(k: u32) -> Property {
    SLOTS[k as usize]
}

/// The slot of `p` past the parameters.
pub fn index(p: Property) -> u32 {
    SLOTS
        .iter()
        .position(|&q| q == p)
        .expect("every property has a slot") as u32
}

/// The property `name` denotes for elements of `domain`, if any.
pub fn lookup(domain: Domain, name: &str) -> Option<Property> {
    ROWS.iter()
        .find(|r| r.name == name && r.domains.contains(&domain))
        .map(|r| r.property)
}

/// The first row of `p`: its name in messages, its range.
pub fn row(p: Property) -> &'static Row {
    ROWS.iter()
        .find(|r| r.property == p)
        .expect("every property has a row")
}

/// Whether `name` is a property of some kind of element (parameters may
/// not take these names).
pub fn is_name(name: &str) -> bool {
    ROWS.iter().any(|r| r.name == name)
}

/// The names without a dot, each once, in table order (the schema's list
/// of reserved parameter names).
pub fn plain_names() -> Vec<&'static str> {
    let mut names: Vec<&'static str> = Vec::new();
    for r in ROWS.iter().filter(|r| !r.name.contains('.')) {
        if !names.contains(&r.name) {
            names.push(r.name);
        }
    }
    names
}

/// The names `domain`'s elements have, for messages: `pos.x/y/z` for
/// the three components, an alias as `degree (= edges)`.
pub fn help(domain: Domain) -> String {
    let mut shown: Vec<String> = Vec::new();
    for r in ROWS.iter().filter(|r| r.domains.contains(&domain)) {
        let canonical = row(r.property).name;
        if canonical != r.name {
            // An alias: written beside the canonical name.
            if let Some(s) = shown.iter_mut().find(|s| s.as_str() == canonical) {
                *s = format!("{canonical} (= {})", r.name);
            }
            continue;
        }
        match r.name.strip_suffix(".x") {
            Some(base) => shown.push(format!("{base}.x/y/z")),
            None if r.name.ends_with(".y") || r.name.ends_with(".z") => {}
            None => shown.push(r.name.to_owned()),
        }
    }
    shown.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_property_round_trips_through_its_slot_and_names() {
        for (k, &p) in SLOTS.iter().enumerate() {
            assert_eq!(index(p), k as u32);
            assert_eq!(at(k as u32), p);
            let r = row(p);
            assert!(!r.domains.is_empty(), "{p:?}");
            for &d in r.domains {
                assert_eq!(lookup(d, r.name), Some(p), "{} on {d:?}", r.name);
            }
        }
        // Every row names a slotted property, and a name means one
        // property per kind of element.
        for r in ROWS {
            assert!(SLOTS.contains(&r.property), "{}", r.name);
            for &d in r.domains {
                let meanings: Vec<Property> = ROWS
                    .iter()
                    .filter(|s| s.name == r.name && s.domains.contains(&d))
                    .map(|s| s.property)
                    .collect();
                assert_eq!(meanings, [r.property], "{} on {d:?}", r.name);
            }
        }
        assert_eq!(lookup(Domain::Face, "edges"), Some(Property::Sides));
        assert_eq!(lookup(Domain::Vert, "edges"), Some(Property::Degree));
        assert_eq!(lookup(Domain::Edge, "edges"), None);
        assert_eq!(lookup(Domain::Vert, "area"), None);
    }

    #[test]
    fn help_lists_names_with_components_and_aliases() {
        assert_eq!(
            help(Domain::Vert),
            "id, random, degree (= edges), faces, age, generation, radius, out_edges, in_edges, pre.length, pos.x/y/z, normal.x/y/z, rel.x/y/z"
        );
        assert!(help(Domain::Face).contains("sides (= edges)"));
        assert!(help(Domain::Edge).contains("dir.x/y/z"));
        assert!(plain_names().contains(&"vert_neighbors") && !plain_names().contains(&"pos.x"));
    }
}
