//! `EXT_meshopt_compression`: bufferViews stored compressed by
//! meshoptimizer's vertex and index codecs (what `gltfpack -c` writes),
//! decoded with the `meshopt` crate (the reference C++ decoder behind a
//! safe interface) before any accessor reads them. The compressed bytes
//! live in another buffer; the view's own buffer is a fallback that may
//! have no data at all, and is not loaded.

use super::*;

/// Bytes one compressed view may decode to, per compressed byte: the vertex
/// codec spends at least 2 bits on a 16-byte group (64 : 1), the index
/// codec at least 4 bits on a triangle of 32-bit indices (24 : 1); four
/// times that is allowed. Checked before allocating, so a hostile `count`
/// costs nothing.
const MAX_EXPANSION: u64 = 256;
/// And beyond that, a few bytes of headers and tail per view.
const EXPANSION_SLACK: u64 = 4096;

/// How a view's elements were encoded (the extension's `mode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Attributes,
    Triangles,
    Indices,
}

/// The reversible transform applied after decoding (`filter`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Filter {
    None,
    Octahedral,
    Quaternion,
    Exponential,
}

/// One compressed bufferView, as the extension describes it.
#[derive(Debug, Clone)]
pub(super) struct CompressedView {
    buffer: usize,
    byte_offset: u64,
    byte_length: u64,
    byte_stride: usize,
    count: usize,
    mode: Mode,
    filter: Filter,
}

/// The extension's objects, taken out of the JSON before it is
/// deserialized: per bufferView its compressed form, and per buffer whether
/// it is only a fallback (no data to load).
pub(super) struct Compression {
    pub views: Vec<Option<CompressedView>>,
    pub fallback_buffers: Vec<bool>,
}

const NAME: &str = "EXT_meshopt_compression";

fn take_extension(object: &mut json::Value) -> Option<json::Value> {
    let extensions = object.get_mut("extensions")?.as_object_mut()?;
    extensions.remove(NAME)
}

/// Reads the extension's objects from `value` (and removes them).
pub(super) fn take_compression(value: &mut json::Value) -> Result<Compression, String> {
    let mut fallback_buffers = Vec::new();
    if let Some(buffers) = value.get_mut("buffers").and_then(|b| b.as_array_mut()) {
        for buffer in buffers {
            let ext = take_extension(buffer);
            fallback_buffers.push(ext.is_some_and(|e| e["fallback"] == json::Value::Bool(true)));
        }
    }
    let mut views = Vec::new();
    if let Some(list) = value.get_mut("bufferViews").and_then(|b| b.as_array_mut()) {
        for (i, view) in list.iter_mut().enumerate() {
            let Some(ext) = take_extension(view) else {
                views.push(None);
                continue;
            };
            let field = |name: &str| -> Result<u64, String> {
                ext.get(name).and_then(json::Value::as_u64).ok_or_else(|| {
                    format!("bufferView {i}: {NAME} needs a non-negative integer `{name}`")
                })
            };
            let mode = match ext.get("mode").and_then(json::Value::as_str) {
                Some("ATTRIBUTES") => Mode::Attributes,
                Some("TRIANGLES") => Mode::Triangles,
                Some("INDICES") => Mode::Indices,
                other => {
                    return Err(format!(
                    "bufferView {i}: {NAME} mode {other:?} is not ATTRIBUTES, TRIANGLES or INDICES"
                ))
                }
            };
            let filter = match ext.get("filter").and_then(json::Value::as_str) {
                None | Some("NONE") => Filter::None,
                Some("OCTAHEDRAL") => Filter::Octahedral,
                Some("QUATERNION") => Filter::Quaternion,
                Some("EXPONENTIAL") => Filter::Exponential,
                Some(other) => {
                    return Err(format!(
                        "bufferView {i}: {NAME} filter {other:?} is not supported"
                    ))
                }
            };
            let too_big = |_| format!("bufferView {i}: {NAME} values too large");
            views.push(Some(CompressedView {
                buffer: usize::try_from(field("buffer")?).map_err(too_big)?,
                byte_offset: ext
                    .get("byteOffset")
                    .and_then(json::Value::as_u64)
                    .unwrap_or(0),
                byte_length: field("byteLength")?,
                byte_stride: usize::try_from(field("byteStride")?).map_err(too_big)?,
                count: usize::try_from(field("count")?).map_err(too_big)?,
                mode,
                filter,
            }));
        }
    }
    Ok(Compression {
        views,
        fallback_buffers,
    })
}

/// Decodes every compressed view from `buffers` (little-endian bytes, as an
/// uncompressed view would hold them).
pub(super) fn decode_views(
    views: &[Option<CompressedView>],
    buffers: &[Cow<'_, [u8]>],
) -> Result<Vec<Option<Vec<u8>>>, String> {
    let total = views
        .iter()
        .flatten()
        .map(|v| (v.byte_stride as u64).saturating_mul(v.count as u64))
        .fold(0u64, u64::saturating_add);
    if total > MAX_DECODED_BYTES {
        return Err(format!(
            "{NAME}: the compressed views decode to {total} bytes, more than the {MAX_DECODED_BYTES} one file may"
        ));
    }
    views
        .iter()
        .enumerate()
        .map(|(i, view)| {
            view.as_ref()
                .map(|v| {
                    decode_view(v, buffers).map_err(|e| format!("bufferView {i}: {NAME}: {e}"))
                })
                .transpose()
        })
        .collect()
}

fn decode_view(view: &CompressedView, buffers: &[Cow<'_, [u8]>]) -> Result<Vec<u8>, String> {
    let buffer = buffers
        .get(view.buffer)
        .ok_or_else(|| format!("buffer {} does not exist", view.buffer))?;
    let end = view.byte_offset.checked_add(view.byte_length);
    let Some(bytes) = end
        .filter(|&e| e <= buffer.len() as u64)
        .map(|e| &buffer[view.byte_offset as usize..e as usize])
    else {
        return Err(format!(
            "{} bytes from byte {} do not fit in buffer {} ({} bytes)",
            view.byte_length,
            view.byte_offset,
            view.buffer,
            buffer.len()
        ));
    };
    let stride = view.byte_stride;
    let decoded = (stride as u64).checked_mul(view.count as u64);
    let limit = MAX_EXPANSION
        .saturating_mul(view.byte_length)
        .saturating_add(EXPANSION_SLACK);
    match decoded {
        Some(n) if n <= limit => {}
        _ => {
            return Err(format!(
                "{} elements of {stride} bytes from {} compressed bytes: more than the codec can encode",
                view.count, view.byte_length
            ))
        }
    }
    let invalid = |e: ::meshopt::Error| format!("the compressed data is invalid ({e})");
    match view.mode {
        Mode::Attributes => {
            if stride == 0 || stride % 4 != 0 || stride > 256 {
                return Err(format!(
                    "byteStride {stride} of ATTRIBUTES is not a multiple of 4 up to 256"
                ));
            }
            let mut words = decode_vertices(bytes, view.count, stride / 4).map_err(invalid)?;
            apply_filter(view.filter, stride, &mut words)?;
            Ok(bytemuck::cast_slice(&words).to_vec())
        }
        Mode::Triangles | Mode::Indices => {
            if view.filter != Filter::None {
                return Err("index data takes no filter".into());
            }
            if view.mode == Mode::Triangles && view.count % 3 != 0 {
                return Err(format!(
                    "TRIANGLES count {} is not a multiple of 3",
                    view.count
                ));
            }
            let sequence = view.mode == Mode::Indices;
            match stride {
                2 => decode_indices::<u16>(bytes, view.count, sequence).map_err(invalid),
                4 => decode_indices::<u32>(bytes, view.count, sequence).map_err(invalid),
                _ => Err(format!("index byteStride {stride} is not 2 or 4")),
            }
        }
    }
}

/// Indices of one width from the index codec (a triangle list, or any
/// sequence), as little-endian bytes of that width.
fn decode_indices<T: ::meshopt::IndexType + Into<u32>>(
    bytes: &[u8],
    count: usize,
    sequence: bool,
) -> ::meshopt::Result<Vec<u8>> {
    let indices: Vec<T> = if sequence {
        ::meshopt::decode_index_sequence(bytes, count)?
    } else {
        ::meshopt::decode_index_buffer(bytes, count)?
    };
    let width = std::mem::size_of::<T>();
    Ok(indices
        .into_iter()
        .flat_map(|i| i.into().to_le_bytes().into_iter().take(width))
        .collect())
}

/// `K` 32-bit words: one vertex of a stride the codec decodes into.
#[derive(Clone, Copy)]
struct Words<const K: usize>([u32; K]);

impl<const K: usize> Default for Words<K> {
    fn default() -> Self {
        Words([0; K])
    }
}

fn decode_words<const K: usize>(bytes: &[u8], count: usize) -> ::meshopt::Result<Vec<u32>> {
    let vertices: Vec<Words<K>> = ::meshopt::decode_vertex_buffer(bytes, count)?;
    Ok(vertices.into_iter().flat_map(|v| v.0).collect())
}

/// The vertex codec's output as 32-bit words (`words` per vertex). The
/// decoder takes the stride from the element type, so each word count has
/// its own instance.
fn decode_vertices(bytes: &[u8], count: usize, words: usize) -> ::meshopt::Result<Vec<u32>> {
    macro_rules! by_words {
        ($($k:literal)*) => {
            match words {
                $($k => decode_words::<$k>(bytes, count),)*
                _ => unreachable!("strides are checked to be 4 to 256"),
            }
        };
    }
    by_words!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30
        31 32 33 34 35 36 37 38 39 40 41 42 43 44 45 46 47 48 49 50 51 52 53 54 55 56 57 58 59
        60 61 62 63 64)
}

/// Undoes the encoder's filter in place (the extension's §Filters; the
/// crate's reference implementations), on the decoded words viewed as the
/// filter's elements (`stride` bytes each; the codec and the filters both
/// work on the bytes as the file holds them).
fn apply_filter(filter: Filter, stride: usize, words: &mut [u32]) -> Result<(), String> {
    use bytemuck::cast_slice_mut as view;
    match (filter, stride) {
        (Filter::None, _) => {}
        // Four 8-bit or four 16-bit components per element.
        (Filter::Octahedral, 4) => ::meshopt::decode_filter_oct(view::<u32, [i8; 4]>(words)),
        (Filter::Octahedral, 8) => ::meshopt::decode_filter_oct(view::<u32, [i16; 4]>(words)),
        (Filter::Octahedral, _) => {
            return Err(format!("OCTAHEDRAL needs byteStride 4 or 8, not {stride}"))
        }
        (Filter::Quaternion, 8) => ::meshopt::decode_filter_quat(view::<u32, [i16; 4]>(words)),
        (Filter::Quaternion, _) => {
            return Err(format!("QUATERNION needs byteStride 8, not {stride}"))
        }
        // Each word decodes on its own: one element of one word each.
        (Filter::Exponential, _) => ::meshopt::decode_filter_exp(view::<u32, [u32; 1]>(words)),
    }
    Ok(())
}
