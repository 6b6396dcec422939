//! `KHR_draco_mesh_compression`: a primitive's indices and attributes
//! stored as one Draco bitstream in a bufferView (Blender's exporter with
//! compression on, `gltf-pipeline -d`, `gltf-transform draco`), decoded
//! with `draco-core` (a pure-Rust Draco decoder) into the bytes each of
//! the primitive's accessors would hold uncompressed. The accessors then
//! read as any others; they have no bufferView of their own.

use super::reader::components;
use super::*;
use draco_core::decode_limits::DecodeLimits;
use draco_core::decoder_buffer::DecoderBuffer;
use draco_core::mesh::Mesh as DracoMesh;
use draco_core::mesh_decoder::MeshDecoder;

const NAME: &str = "KHR_draco_mesh_compression";

/// One compressed primitive: where its bitstream is, and which Draco
/// attribute (by unique id) holds each glTF attribute.
#[derive(Debug, Clone)]
pub(super) struct DracoPrimitive {
    mesh: usize,
    primitive: usize,
    buffer_view: usize,
    attributes: Vec<(String, u32)>,
}

/// Takes the extension's objects out of `value`'s primitives.
pub(super) fn take_draco(value: &mut json::Value) -> Result<Vec<DracoPrimitive>, String> {
    let mut out = Vec::new();
    let Some(meshes) = value.get_mut("meshes").and_then(|m| m.as_array_mut()) else {
        return Ok(out);
    };
    for (m, mesh) in meshes.iter_mut().enumerate() {
        let Some(primitives) = mesh.get_mut("primitives").and_then(|p| p.as_array_mut()) else {
            continue;
        };
        for (p, primitive) in primitives.iter_mut().enumerate() {
            let Some(ext) = primitive
                .get_mut("extensions")
                .and_then(|e| e.as_object_mut())
                .and_then(|e| e.remove(NAME))
            else {
                continue;
            };
            let context = format!("mesh {m} primitive {p}: {NAME}");
            let buffer_view = ext
                .get("bufferView")
                .and_then(json::Value::as_u64)
                .and_then(|v| usize::try_from(v).ok())
                .ok_or_else(|| format!("{context} needs a bufferView"))?;
            let attributes = ext
                .get("attributes")
                .and_then(json::Value::as_object)
                .ok_or_else(|| format!("{context} needs attributes"))?
                .iter()
                .map(|(name, id)| {
                    id.as_u64()
                        .and_then(|id| u32::try_from(id).ok())
                        .map(|id| (name.clone(), id))
                        .ok_or_else(|| format!("{context}: attribute {name} needs an id"))
                })
                .collect::<Result<_, _>>()?;
            out.push(DracoPrimitive {
                mesh: m,
                primitive: p,
                buffer_view,
                attributes,
            });
        }
    }
    Ok(out)
}

/// Decodes every compressed primitive: per accessor, the bytes it would
/// hold uncompressed (tightly packed, little-endian, its own component
/// type).
pub(super) fn decode_accessors(
    primitives: &[DracoPrimitive],
    root: &json::Root,
    custom: &[Vec<Vec<(String, u64)>>],
    buffers: &[Cow<'_, [u8]>],
) -> Result<Vec<Option<Vec<u8>>>, String> {
    let mut decoded: Vec<Option<Vec<u8>>> = vec![None; root.accessors.len()];
    // One budget for the whole file: each stream may use what is left.
    let mut budget = MAX_DECODED_BYTES;
    for draco in primitives {
        let context = format!("mesh {} primitive {}: {NAME}", draco.mesh, draco.primitive);
        let err = |message: String| format!("{context}: {message}");
        // Taken from the same JSON that was parsed: the indices exist.
        let primitive = &root.meshes[draco.mesh].primitives[draco.primitive];
        let view = root
            .buffer_views
            .get(draco.buffer_view)
            .ok_or_else(|| err(format!("bufferView {} does not exist", draco.buffer_view)))?;
        let buffer = buffers
            .get(view.buffer.value())
            .ok_or_else(|| err(format!("buffer {} does not exist", view.buffer.value())))?;
        let start = view.byte_offset.map_or(0, |o| o.0);
        let end = start.checked_add(view.byte_length.0);
        let Some(stream) = end
            .filter(|&e| e <= buffer.len() as u64)
            .map(|e| &buffer[start as usize..e as usize])
        else {
            return Err(err(format!(
                "bufferView {} does not fit in its buffer",
                draco.buffer_view
            )));
        };
        // Draco's own ceilings on what one stream may claim, checked as it
        // decodes (before it allocates what a header asks for).
        let limits = DecodeLimits::default()
            .with_max_decoded_bytes(budget)
            .with_max_faces(budget / 12);
        let mut input = DecoderBuffer::new(stream).with_limits(limits);
        let mut mesh = DracoMesh::new();
        MeshDecoder::new()
            .decode(&mut input, &mut mesh)
            .map_err(|e| err(format!("the Draco stream does not decode ({e})")))?;
        let points = mesh.num_points();
        let mut put = |accessor: usize, bytes: Vec<u8>| -> Result<(), String> {
            budget = budget.checked_sub(bytes.len() as u64).ok_or_else(|| {
                err(format!(
                    "the streams decode to more than the {MAX_DECODED_BYTES} bytes one file may"
                ))
            })?;
            let slot = decoded
                .get_mut(accessor)
                .ok_or_else(|| err(format!("accessor {accessor} does not exist")))?;
            if slot.is_some() {
                return Err(err(format!(
                    "accessor {accessor} is used by two compressed primitives"
                )));
            }
            *slot = Some(bytes);
            Ok(())
        };
        if let Some(indices) = &primitive.indices {
            let accessor = root
                .accessors
                .get(indices.value())
                .ok_or_else(|| err(format!("accessor {} does not exist", indices.value())))?;
            let values: Vec<f64> = mesh
                .faces()
                .iter()
                .flatten()
                .map(|p| f64::from(p.0))
                .collect();
            if values.iter().any(|&i| i >= points as f64) {
                return Err(err("a face names a point the stream does not have".into()));
            }
            put(indices.value(), packed(accessor, &values)?)?;
        }
        for (semantic, id) in &draco.attributes {
            let Some(attribute) = mesh.attribute_by_unique_id(*id) else {
                return Err(err(format!(
                    "attribute {semantic}: the stream has no attribute {id}"
                )));
            };
            // The semantic as the file spells it (gltf-json's parser of it
            // is private; its serializer gives the same text back).
            let spelled = |s: &Checked<json::mesh::Semantic>| match s {
                Checked::Valid(s) => serde_json::to_value(s).ok(),
                Checked::Invalid => None,
            };
            // `_NAME` attributes were taken out of the primitive before it
            // was parsed (`take_custom_attributes`, which keeps NAME): they
            // are looked up there.
            let named = primitive.attributes.iter().find_map(|(s, i)| {
                (spelled(s).as_ref().and_then(json::Value::as_str) == Some(semantic.as_str()))
                    .then_some(i.value())
            });
            let custom_named = || {
                custom
                    .get(draco.mesh)?
                    .get(draco.primitive)?
                    .iter()
                    .find(|(name, _)| semantic.strip_prefix('_') == Some(name.as_str()))
                    .and_then(|&(_, i)| usize::try_from(i).ok())
            };
            let Some(index) = named.or_else(custom_named) else {
                // Compressed but not named by the primitive: not read.
                continue;
            };
            let accessor = root
                .accessors
                .get(index)
                .ok_or_else(|| err(format!("{semantic}: accessor {index} does not exist")))?;
            let dims = components(&accessor.type_)
                .ok_or_else(|| err(format!("{semantic}: unsupported type")))?;
            if accessor.count.0 != points as u64 {
                return Err(err(format!(
                    "{semantic}: the accessor counts {} vertices, the stream decodes {points}",
                    accessor.count.0
                )));
            }
            let values: Vec<f64> = attribute
                .read_f32s(points, dims)
                .into_iter()
                .map(f64::from)
                .collect();
            put(index, packed(accessor, &values)?)?;
        }
    }
    Ok(decoded)
}

/// `values` as the accessor's component type would store them (Draco
/// decodes integer attributes to their integers, floats to floats). The
/// reader checks the length against the accessor's count and type.
fn packed(accessor: &json::Accessor, values: &[f64]) -> Result<Vec<u8>, String> {
    use json::accessor::ComponentType as C;
    let Checked::Valid(json::accessor::GenericComponentType(component)) = accessor.component_type
    else {
        return Err("invalid componentType".into());
    };
    let (low, high) = match component {
        C::F32 => (f64::NEG_INFINITY, f64::INFINITY),
        C::U32 => (0.0, f64::from(u32::MAX)),
        C::U16 => (0.0, f64::from(u16::MAX)),
        C::I16 => (f64::from(i16::MIN), f64::from(i16::MAX)),
        C::U8 => (0.0, f64::from(u8::MAX)),
        C::I8 => (f64::from(i8::MIN), f64::from(i8::MAX)),
    };
    if let Some(v) = values.iter().find(|&&v| v < low || v > high) {
        return Err(format!(
            "the decoded value {v} does not fit the accessor's {component:?}"
        ));
    }
    let mut out = Vec::with_capacity(values.len() * 4);
    for &v in values {
        match component {
            C::F32 => out.extend_from_slice(&(v as f32).to_le_bytes()),
            C::U32 => out.extend_from_slice(&(v as u32).to_le_bytes()),
            C::U16 => out.extend_from_slice(&(v as u16).to_le_bytes()),
            C::I16 => out.extend_from_slice(&(v as i16).to_le_bytes()),
            C::U8 => out.push(v as u8),
            C::I8 => out.push(v as i8 as u8),
        }
    }
    Ok(out)
}
