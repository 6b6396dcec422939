//! Named per-element attribute layers.
//!
//! A layer stores one value per arena slot of its domain (vertex, edge or
//! face): scalars (`f64`), vectors (`DVec3`) or integers (`i64`). Later stages
//! keep node radius, turtle frame and age here. Layers are kept sorted by
//! (domain, name) so iteration order, and therefore output, is deterministic.
//!
//! Euler operators give new elements the layer's default value or carry
//! values over (split edge interpolates, split face copies); high-level
//! operators copy from the element they derive a new one from.

use glam::DVec3;

use super::ids::Domain;

/// The values of one layer, indexed by slot.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerData {
    Scalar(Vec<f64>),
    Vector(Vec<DVec3>),
    Int(Vec<i64>),
}

/// The kind of value a layer stores.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum LayerKind {
    Scalar,
    Vector,
    Int,
}

/// A single attribute value.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum AttrValue {
    Scalar(f64),
    Vector(DVec3),
    Int(i64),
}

impl AttrValue {
    pub fn kind(self) -> LayerKind {
        match self {
            AttrValue::Scalar(_) => LayerKind::Scalar,
            AttrValue::Vector(_) => LayerKind::Vector,
            AttrValue::Int(_) => LayerKind::Int,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    pub name: String,
    pub domain: Domain,
    pub default: AttrValue,
    pub data: LayerData,
}

impl Layer {
    fn new(name: &str, domain: Domain, default: AttrValue, len: usize) -> Self {
        let data = match default {
            AttrValue::Scalar(x) => LayerData::Scalar(vec![x; len]),
            AttrValue::Vector(x) => LayerData::Vector(vec![x; len]),
            AttrValue::Int(x) => LayerData::Int(vec![x; len]),
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

    pub fn len(&self) -> usize {
        match &self.data {
            LayerData::Scalar(v) => v.len(),
            LayerData::Vector(v) => v.len(),
            LayerData::Int(v) => v.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn get(&self, slot: usize) -> AttrValue {
        match &self.data {
            LayerData::Scalar(v) => AttrValue::Scalar(v[slot]),
            LayerData::Vector(v) => AttrValue::Vector(v[slot]),
            LayerData::Int(v) => AttrValue::Int(v[slot]),
        }
    }

    fn ensure_len(&mut self, len: usize) {
        match (&mut self.data, self.default) {
            (LayerData::Scalar(v), AttrValue::Scalar(d)) if v.len() < len => v.resize(len, d),
            (LayerData::Vector(v), AttrValue::Vector(d)) if v.len() < len => v.resize(len, d),
            (LayerData::Int(v), AttrValue::Int(d)) if v.len() < len => v.resize(len, d),
            _ => {}
        }
    }

    fn reset(&mut self, slot: usize) {
        self.ensure_len(slot + 1);
        match (&mut self.data, self.default) {
            (LayerData::Scalar(v), AttrValue::Scalar(d)) => v[slot] = d,
            (LayerData::Vector(v), AttrValue::Vector(d)) => v[slot] = d,
            (LayerData::Int(v), AttrValue::Int(d)) => v[slot] = d,
            _ => unreachable!("layer data and default always share a kind"),
        }
    }

    fn copy(&mut self, from: usize, to: usize) {
        self.ensure_len(from.max(to) + 1);
        match &mut self.data {
            LayerData::Scalar(v) => v[to] = v[from],
            LayerData::Vector(v) => v[to] = v[from],
            LayerData::Int(v) => v[to] = v[from],
        }
    }

    /// Linear blend; integers take the value of the nearer end.
    fn interpolate(&mut self, a: usize, b: usize, t: f64, to: usize) {
        self.ensure_len(a.max(b).max(to) + 1);
        match &mut self.data {
            LayerData::Scalar(v) => v[to] = v[a] + (v[b] - v[a]) * t,
            LayerData::Vector(v) => v[to] = v[a].lerp(v[b], t),
            LayerData::Int(v) => v[to] = if t < 0.5 { v[a] } else { v[b] },
        }
    }

    fn set(&mut self, slot: usize, value: AttrValue) -> Result<(), LayerKind> {
        self.ensure_len(slot + 1);
        match (&mut self.data, value) {
            (LayerData::Scalar(v), AttrValue::Scalar(x)) => v[slot] = x,
            (LayerData::Vector(v), AttrValue::Vector(x)) => v[slot] = x,
            (LayerData::Int(v), AttrValue::Int(x)) => v[slot] = x,
            _ => return Err(self.kind()),
        }
        Ok(())
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
        capacity: usize,
    ) -> Result<usize, LayerKind> {
        match self.find(name, domain) {
            Some(i) if self.layers[i].kind() == default.kind() => Ok(i),
            Some(i) => Err(self.layers[i].kind()),
            None => {
                let layer = Layer::new(name, domain, default, capacity);
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

    pub(crate) fn on_new(&mut self, domain: Domain, slot: usize) {
        for layer in self.layers.iter_mut().filter(|l| l.domain == domain) {
            layer.reset(slot);
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
