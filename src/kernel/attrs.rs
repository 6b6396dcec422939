//! Named per-element attribute layers.
//!
//! A layer holds one value per arena slot of its domain (vertex, edge or
//! face): scalars (`f64`), vectors (`DVec3`), integers (`i32`) or opaque
//! 64-bit keys. Later stages keep node radius, turtle frame, age, part,
//! material and the random-stream lineage here.
//! Layers are kept sorted by (domain, name) so iteration order, and
//! therefore output, is deterministic.
//!
//! Scalar, vector and integer layers store, per slot, a narrow index into
//! the layer's distinct values while values repeat (`pooled.rs`): turtle
//! frames, ages and radii do, and this is most of the memory saved at 10⁶
//! G³ primitives. Lineage keys never repeat and are stored plainly.
//!
//! Storage is a prefix: values are stored for slots `0..len()` and every
//! slot past it holds the layer's default. A layer that is never given
//! another value (the part and material of a model without looks, say)
//! costs nothing however many elements the mesh grows, and new elements
//! past the stored prefix need no write. Writing a non-default value past
//! the prefix extends it. "Default" is bitwise, so `-0.0` is stored.
//!
//! Euler operators give new elements the layer's default value or carry
//! values over (split edge interpolates, split face copies); high-level
//! operators copy from the element they derive a new one from.

use glam::DVec3;

use super::ids::Domain;
use super::pooled::Stored;

/// The stored prefix of one layer's values, indexed by slot (pooled while
/// values repeat: `pooled.rs`).
#[derive(Clone, Debug)]
pub enum LayerData {
    Scalar(Stored<f64>),
    Vector(Stored<DVec3>),
    Int(Stored<i32>),
    /// Lineage keys: never repeat, so never pooled.
    Key(Stored<u64>),
}

/// Runs `$body` on the layer data's storage, whatever its kind.
macro_rules! each {
    ($data:expr, $v:ident => $body:expr) => {
        match $data {
            LayerData::Scalar($v) => $body,
            LayerData::Vector($v) => $body,
            LayerData::Int($v) => $body,
            LayerData::Key($v) => $body,
        }
    };
}

/// The kind of value a layer stores.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum LayerKind {
    Scalar,
    Vector,
    Int,
    /// An opaque 64-bit value: copied, never blended.
    Key,
}

/// A single attribute value.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum AttrValue {
    Scalar(f64),
    Vector(DVec3),
    Int(i32),
    Key(u64),
}

impl AttrValue {
    pub fn kind(self) -> LayerKind {
        match self {
            AttrValue::Scalar(_) => LayerKind::Scalar,
            AttrValue::Vector(_) => LayerKind::Vector,
            AttrValue::Int(_) => LayerKind::Int,
            AttrValue::Key(_) => LayerKind::Key,
        }
    }

    /// Bit-for-bit equality (`-0.0 ≠ 0.0`, a NaN equals the same NaN): what
    /// decides whether a value needs storing.
    fn same_bits(self, other: AttrValue) -> bool {
        match (self, other) {
            (AttrValue::Scalar(a), AttrValue::Scalar(b)) => a.to_bits() == b.to_bits(),
            (AttrValue::Vector(a), AttrValue::Vector(b)) => {
                a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits)
            }
            (AttrValue::Int(a), AttrValue::Int(b)) => a == b,
            (AttrValue::Key(a), AttrValue::Key(b)) => a == b,
            _ => false,
        }
    }
}

#[derive(Clone, Debug)]
pub struct Layer {
    pub name: String,
    pub domain: Domain,
    pub default: AttrValue,
    data: LayerData,
}

/// Layers are equal when they agree on every slot, however long the
/// stored prefixes are.
impl PartialEq for Layer {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
            && self.domain == other.domain
            && self.default == other.default
            && (0..self.len().max(other.len())).all(|i| self.get(i) == other.get(i))
    }
}

impl Layer {
    fn new(name: &str, domain: Domain, default: AttrValue) -> Self {
        let data = match default {
            AttrValue::Scalar(d) => LayerData::Scalar(Stored::pooled(d)),
            AttrValue::Vector(d) => LayerData::Vector(Stored::pooled(d)),
            AttrValue::Int(d) => LayerData::Int(Stored::pooled(d)),
            AttrValue::Key(_) => LayerData::Key(Stored::plain()),
        };
        Self {
            name: name.to_owned(),
            domain,
            default,
            data,
        }
    }

    pub fn kind(&self) -> LayerKind {
        self.default.kind()
    }

    /// How many slots have a stored value (every later slot holds the
    /// default).
    pub fn len(&self) -> usize {
        each!(&self.data, v => v.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes of the stored prefix (indices and distinct values) in use and
    /// allocated.
    pub fn bytes(&self) -> (usize, usize) {
        each!(&self.data, v => v.bytes())
    }

    /// Room for `additional` more stored slots, grown as
    /// [`super::arena::Arena::reserve_growth`] grows an arena.
    fn reserve_growth(&mut self, additional: usize) {
        each!(&mut self.data, v => v.reserve_growth(additional))
    }

    /// The value of `slot` (the default past the stored prefix).
    #[inline]
    pub fn get(&self, slot: usize) -> AttrValue {
        match &self.data {
            LayerData::Scalar(v) => v.get(slot).map_or(self.default, AttrValue::Scalar),
            LayerData::Vector(v) => v.get(slot).map_or(self.default, AttrValue::Vector),
            LayerData::Int(v) => v.get(slot).map_or(self.default, AttrValue::Int),
            LayerData::Key(v) => v.get(slot).map_or(self.default, AttrValue::Key),
        }
    }

    /// A scalar layer's value of `slot`; `None` for other kinds.
    #[inline]
    pub fn scalar(&self, slot: usize) -> Option<f64> {
        match (&self.data, self.default) {
            (LayerData::Scalar(v), AttrValue::Scalar(d)) => Some(v.get(slot).unwrap_or(d)),
            _ => None,
        }
    }

    fn extend_to(&mut self, len: usize) {
        match (&mut self.data, self.default) {
            (LayerData::Scalar(v), AttrValue::Scalar(d)) => v.extend_to(len, d),
            (LayerData::Vector(v), AttrValue::Vector(d)) => v.extend_to(len, d),
            (LayerData::Int(v), AttrValue::Int(d)) => v.extend_to(len, d),
            (LayerData::Key(v), AttrValue::Key(d)) => v.extend_to(len, d),
            _ => unreachable!("layer data and default always share a kind"),
        }
    }

    /// A new element in `slot`: the default, which past the prefix is
    /// already what the slot reads.
    fn reset(&mut self, slot: usize) {
        if slot < self.len() {
            self.write(slot, self.default);
        }
    }

    fn copy(&mut self, from: usize, to: usize) {
        let len = self.len();
        if from < len {
            if to >= len {
                if self.get(from).same_bits(self.default) {
                    return;
                }
                self.extend_to(to + 1);
            }
            // A pooled layer shares the value's index: a new element (past
            // the prefix) copying an old one's frame must not add the frame
            // to the table again (the cache of recent values rarely holds
            // it), where the next write would leave it dead.
            each!(&mut self.data, v => v.copy(from, to));
            return;
        }
        let value = self.get(from);
        self.store(to, value);
    }

    /// Linear blend; integers and keys take the value of the nearer end.
    fn interpolate(&mut self, a: usize, b: usize, t: f64, to: usize) {
        let value = match (self.get(a), self.get(b)) {
            (AttrValue::Scalar(x), AttrValue::Scalar(y)) => AttrValue::Scalar(x + (y - x) * t),
            (AttrValue::Vector(x), AttrValue::Vector(y)) => AttrValue::Vector(x.lerp(y, t)),
            (x, y) => {
                if t < 0.5 {
                    x
                } else {
                    y
                }
            }
        };
        self.store(to, value);
    }

    fn set(&mut self, slot: usize, value: AttrValue) -> Result<(), LayerKind> {
        if value.kind() != self.kind() {
            return Err(self.kind());
        }
        self.store(slot, value);
        Ok(())
    }

    /// Stores scalar values, slot by slot, as [`Layer::set`] would one at a time, but in one pass
    /// over the storage ([`Stored::write_many`]). Every slot lies below `end`.
    fn set_scalars(
        &mut self,
        end: usize,
        values: impl IntoIterator<Item = (usize, f64)>,
    ) -> Result<(), LayerKind> {
        let (LayerData::Scalar(stored), AttrValue::Scalar(default)) =
            (&mut self.data, self.default)
        else {
            return Err(self.kind());
        };
        stored.write_many(default, end, values);
        Ok(())
    }

    /// Stores a value of the layer's kind, extending the prefix only for a
    /// value that is not the default.
    fn store(&mut self, slot: usize, value: AttrValue) {
        if slot >= self.len() {
            if value.same_bits(self.default) {
                return;
            }
            self.extend_to(slot + 1);
        }
        self.write(slot, value);
    }

    fn write(&mut self, slot: usize, value: AttrValue) {
        match (&mut self.data, value) {
            (LayerData::Scalar(v), AttrValue::Scalar(x)) => v.write(slot, x),
            (LayerData::Vector(v), AttrValue::Vector(x)) => v.write(slot, x),
            (LayerData::Int(v), AttrValue::Int(x)) => v.write(slot, x),
            (LayerData::Key(v), AttrValue::Key(x)) => v.write(slot, x),
            _ => unreachable!("layer data and value share a kind (checked by the caller)"),
        }
    }
}

/// All attribute layers of a mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Attributes {
    layers: Vec<Layer>,
}

impl Attributes {
    /// Adds a layer (or returns the existing one's index if name, domain and kind match).
    pub(crate) fn add_layer(
        &mut self,
        name: &str,
        domain: Domain,
        default: AttrValue,
    ) -> Result<usize, LayerKind> {
        match self.find(name, domain) {
            Some(i) if self.layers[i].kind() == default.kind() => Ok(i),
            Some(i) => Err(self.layers[i].kind()),
            None => {
                let layer = Layer::new(name, domain, default);
                let at = self
                    .layers
                    .partition_point(|l| (l.domain, l.name.as_str()) < (domain, name));
                self.layers.insert(at, layer);
                Ok(at)
            }
        }
    }

    pub fn find(&self, name: &str, domain: Domain) -> Option<usize> {
        self.layers
            .iter()
            .position(|l| l.domain == domain && l.name == name)
    }

    pub fn layers(&self) -> &[Layer] {
        &self.layers
    }

    pub fn layer(&self, name: &str, domain: Domain) -> Option<&Layer> {
        self.find(name, domain).map(|i| &self.layers[i])
    }

    pub(crate) fn remove_layer(&mut self, name: &str, domain: Domain) -> bool {
        match self.find(name, domain) {
            Some(i) => {
                self.layers.remove(i);
                true
            }
            None => false,
        }
    }

    pub(crate) fn set(
        &mut self,
        name: &str,
        domain: Domain,
        slot: usize,
        value: AttrValue,
    ) -> Option<Result<(), LayerKind>> {
        let i = self.find(name, domain)?;
        Some(self.layers[i].set(slot, value))
    }

    /// Many [`Attributes::set`]s of one scalar layer, the layer looked up once.
    pub(crate) fn set_scalars(
        &mut self,
        name: &str,
        domain: Domain,
        end: usize,
        values: impl IntoIterator<Item = (usize, f64)>,
    ) -> Option<Result<(), LayerKind>> {
        let i = self.find(name, domain)?;
        Some(self.layers[i].set_scalars(end, values))
    }

    pub(crate) fn on_new(&mut self, domain: Domain, slot: usize) {
        for layer in self.layers.iter_mut().filter(|l| l.domain == domain) {
            layer.reset(slot);
        }
    }

    /// Reserves `additional` slots in each layer of `domain` whose stored
    /// prefix reaches `slots` (every element so far was given a value, so
    /// the new ones likely will be too).
    pub(crate) fn reserve_growth(&mut self, domain: Domain, slots: usize, additional: usize) {
        for layer in self.layers.iter_mut().filter(|l| l.domain == domain) {
            if layer.len() >= slots {
                layer.reserve_growth(additional);
            }
        }
    }

    pub(crate) fn copy(&mut self, domain: Domain, from: usize, to: usize) {
        for layer in self.layers.iter_mut().filter(|l| l.domain == domain) {
            layer.copy(from, to);
        }
    }

    pub(crate) fn interpolate(&mut self, domain: Domain, a: usize, b: usize, t: f64, to: usize) {
        for layer in self.layers.iter_mut().filter(|l| l.domain == domain) {
            layer.interpolate(a, b, t, to);
        }
    }

    /// Copies `from` (a slot of `source`) into slot `to` of the same-named layer here.
    pub(crate) fn copy_from(
        &mut self,
        source: &Attributes,
        domain: Domain,
        from: usize,
        to: usize,
    ) {
        for layer in source.layers.iter().filter(|l| l.domain == domain) {
            if let Some(i) = self.find(&layer.name, domain) {
                let _ = self.layers[i].set(to, layer.get(from));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn layer(default: AttrValue) -> Layer {
        Layer::new("x", Domain::Vert, default)
    }

    /// A new element past the stored prefix copying an old one's value
    /// shares its entry: the table gains nothing (G³ nodes copy a frame
    /// written long before, which the cache of recent values has lost).
    #[test]
    fn a_copy_past_the_prefix_shares_the_value() {
        let mut l = layer(AttrValue::Vector(DVec3::ZERO));
        let n = 3000;
        for slot in 0..n {
            let v = DVec3::new(slot as f64 + 1.0, 2.0, 3.0);
            l.set(slot, AttrValue::Vector(v)).unwrap();
        }
        let before = l.bytes().0;
        l.copy(0, 2 * n);
        assert_eq!(l.get(2 * n), l.get(0));
        assert_eq!(l.get(2 * n - 1), AttrValue::Vector(DVec3::ZERO));
        // Two-byte indices for the n + 1 new slots, no new value.
        assert_eq!(l.bytes().0 - before, 2 * (n + 1));
        // A default copied past the prefix stores nothing.
        let len = l.len();
        l.copy(2 * n - 1, 3 * n);
        assert_eq!(l.len(), len);
    }

    #[test]
    fn a_layer_stores_nothing_until_a_value_differs_from_its_default() {
        let mut l = layer(AttrValue::Int(-1));
        for slot in 0..1000 {
            l.reset(slot);
            l.copy(slot / 2, slot);
            l.interpolate(0, slot, 0.7, slot);
            l.set(slot, AttrValue::Int(-1)).unwrap();
        }
        assert_eq!(l.len(), 0);
        assert_eq!(l.get(999), AttrValue::Int(-1));
        l.set(10, AttrValue::Int(4)).unwrap();
        assert_eq!(l.len(), 11);
        assert_eq!(
            (l.get(9), l.get(10), l.get(11)),
            (AttrValue::Int(-1), AttrValue::Int(4), AttrValue::Int(-1))
        );
        // A new element inside the prefix is given the default again.
        l.reset(10);
        assert_eq!(l.get(10), AttrValue::Int(-1));
        assert_eq!(l.set(3, AttrValue::Scalar(1.0)), Err(LayerKind::Int));
    }

    #[test]
    fn defaults_are_compared_bit_for_bit() {
        let mut l = layer(AttrValue::Scalar(0.0));
        l.set(5, AttrValue::Scalar(0.0)).unwrap();
        assert_eq!(l.len(), 0);
        l.set(5, AttrValue::Scalar(-0.0)).unwrap();
        assert_eq!(l.len(), 6);
        let AttrValue::Scalar(x) = l.get(5) else {
            unreachable!()
        };
        assert!(x == 0.0 && x.is_sign_negative());
        let mut v = layer(AttrValue::Vector(DVec3::Z));
        v.interpolate(0, 1, 0.5, 2);
        assert_eq!(v.len(), 0);
        v.set(1, AttrValue::Vector(DVec3::X)).unwrap();
        v.interpolate(0, 1, 0.5, 3);
        assert_eq!(v.get(3), AttrValue::Vector(DVec3::new(0.5, 0.0, 0.5)));
    }

    #[test]
    fn layers_are_equal_by_value_whatever_their_stored_length() {
        let mut a = layer(AttrValue::Scalar(1.0));
        let mut b = layer(AttrValue::Scalar(1.0));
        a.set(7, AttrValue::Scalar(2.0)).unwrap();
        b.set(7, AttrValue::Scalar(2.0)).unwrap();
        b.set(20, AttrValue::Scalar(3.0)).unwrap();
        assert_ne!(a, b);
        b.set(20, AttrValue::Scalar(1.0)).unwrap();
        assert_eq!(a, b);
        assert!(a.len() < b.len());
    }

    #[test]
    fn scalars_set_in_one_call_read_as_one_set_each() {
        let mut one = Attributes::default();
        let mut many = Attributes::default();
        for a in [&mut one, &mut many] {
            a.add_layer("u", Domain::Vert, AttrValue::Scalar(0.5))
                .unwrap();
            a.add_layer("k", Domain::Vert, AttrValue::Int(0)).unwrap();
        }
        // Defaults past the prefix, a grid's cycling values, then a slot rewritten.
        let values: Vec<(usize, f64)> = (0..3000)
            .map(|k| {
                (
                    k + 10,
                    if k % 5 == 0 {
                        0.5
                    } else {
                        (k % 700) as f64 * 0.25
                    },
                )
            })
            .chain([(12, -1.0), (5000, 0.5)])
            .collect();
        for &(slot, x) in &values {
            one.set("u", Domain::Vert, slot, AttrValue::Scalar(x))
                .unwrap()
                .unwrap();
        }
        many.set_scalars("u", Domain::Vert, 5001, values.iter().copied())
            .unwrap()
            .unwrap();
        assert_eq!(many, one);
        let u = many.layer("u", Domain::Vert).unwrap();
        assert_eq!(u.len(), 5001, "grown to the end at once");
        assert_eq!(u.get(4000), AttrValue::Scalar(0.5));
        // Only defaults past the prefix store nothing.
        let mut defaults = Attributes::default();
        defaults
            .add_layer("u", Domain::Vert, AttrValue::Scalar(0.5))
            .unwrap();
        defaults.set_scalars("u", Domain::Vert, 100, (0..100).map(|k| (k, 0.5)));
        assert!(defaults.layer("u", Domain::Vert).unwrap().is_empty());
        assert_eq!(u.get(12), AttrValue::Scalar(-1.0));
        assert_eq!(u.get(11), AttrValue::Scalar(0.25));
        // Another kind's layer refuses and keeps its values; a missing layer is `None`.
        let before = many.clone();
        let refused = many.set_scalars("k", Domain::Vert, 3, [(1, 2.0)]);
        assert_eq!(refused, Some(Err(LayerKind::Int)));
        assert!(many.set_scalars("w", Domain::Vert, 3, [(1, 2.0)]).is_none());
        assert_eq!(many, before);
    }
}
