//! A file's bytes as consecutive parts.
//!
//! A writer that builds its big arrays as columns (a GLB's positions,
//! normals and indices) hands the columns over as they are instead of
//! copying them into one buffer: the caller writes and hashes the parts in
//! order. For a GLB of 1M triangles that is 24 MB neither allocated, first
//! touched nor copied (issue 38: the floor of a write is the memory it
//! touches, on any machine).

/// The bytes of one file, in order: [`FileParts::iter`] gives them as
/// slices, [`FileParts::into_vec`] as one buffer.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct FileParts {
    parts: Vec<Part>,
    len: usize,
}

/// One run of a file's bytes; number columns are little-endian in the file.
#[derive(Debug, Clone, PartialEq)]
enum Part {
    Bytes(Vec<u8>),
    F32(Vec<f32>),
    U32(Vec<u32>),
}

impl Part {
    fn as_bytes(&self) -> &[u8] {
        match self {
            Part::Bytes(b) => b,
            Part::F32(v) => bytemuck::cast_slice(v),
            Part::U32(v) => bytemuck::cast_slice(v),
        }
    }
}

impl FileParts {
    /// Total length in bytes.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Appends `bytes` as a part of its own.
    pub fn push_bytes(&mut self, bytes: Vec<u8>) {
        if !bytes.is_empty() {
            self.len += bytes.len();
            self.parts.push(Part::Bytes(bytes));
        }
    }

    /// Appends a column of `f32`s, written little-endian: taken as it is
    /// on a little-endian machine.
    pub fn push_f32s(&mut self, values: Vec<f32>) {
        self.push_column(values, Part::F32);
    }

    /// Appends a column of `u32`s, written little-endian.
    pub fn push_u32s(&mut self, values: Vec<u32>) {
        self.push_column(values, Part::U32);
    }

    fn push_column<T: bytemuck::Pod>(&mut self, values: Vec<T>, part: fn(Vec<T>) -> Part) {
        if cfg!(target_endian = "little") {
            self.len += std::mem::size_of_val(&values[..]);
            self.parts.push(part(values));
        } else {
            // Each value's bytes reversed: little-endian.
            let bytes: &[u8] = bytemuck::cast_slice(&values);
            let size = std::mem::size_of::<T>();
            self.push_bytes(
                bytes
                    .chunks(size)
                    .flat_map(|c| c.iter().rev())
                    .copied()
                    .collect(),
            );
        }
    }

    /// The parts in file order.
    pub fn iter(&self) -> impl Iterator<Item = &[u8]> {
        self.parts.iter().map(Part::as_bytes)
    }

    /// The file as one slice: borrowed when it is one part, else joined.
    pub fn joined(&self) -> std::borrow::Cow<'_, [u8]> {
        match &self.parts[..] {
            [] => std::borrow::Cow::Borrowed(&[]),
            [one] => std::borrow::Cow::Borrowed(one.as_bytes()),
            _ => std::borrow::Cow::Owned(self.clone().into_vec()),
        }
    }

    /// The file as one buffer (a copy of every column but a lone bytes part).
    pub fn into_vec(mut self) -> Vec<u8> {
        if let [Part::Bytes(_)] = self.parts[..] {
            if let Some(Part::Bytes(bytes)) = self.parts.pop() {
                return bytes;
            }
        }
        let mut out = Vec::with_capacity(self.len);
        for part in self.iter() {
            out.extend_from_slice(part);
        }
        out
    }
}

impl From<Vec<u8>> for FileParts {
    fn from(bytes: Vec<u8>) -> Self {
        FileParts {
            len: bytes.len(),
            parts: vec![Part::Bytes(bytes)],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_join_in_order_little_endian() {
        let mut parts = FileParts::default();
        parts.push_bytes(b"ab".to_vec());
        parts.push_bytes(Vec::new());
        parts.push_bytes(b"c".to_vec());
        parts.push_f32s(vec![1.0, -2.5]);
        parts.push_u32s(vec![7, 0x0102_0304]);
        parts.push_bytes(b"z".to_vec());
        let mut want = b"abc".to_vec();
        for x in [1.0f32, -2.5] {
            want.extend_from_slice(&x.to_le_bytes());
        }
        for x in [7u32, 0x0102_0304] {
            want.extend_from_slice(&x.to_le_bytes());
        }
        want.push(b'z');
        assert_eq!(parts.len(), want.len());
        assert_eq!(parts.iter().map(<[u8]>::len).sum::<usize>(), want.len());
        assert_eq!(parts.iter().count(), 5, "an empty part is left out");
        assert_eq!(parts.joined(), &want[..]);
        assert_eq!(parts.clone().into_vec(), want);
        let whole = FileParts::from(want.clone());
        assert_eq!(whole.len(), want.len());
        assert!(matches!(whole.joined(), std::borrow::Cow::Borrowed(b) if b == &want[..]));
        assert_eq!(whole.into_vec(), want);
        assert!(FileParts::default().is_empty());
        assert_eq!(FileParts::default().into_vec(), Vec::<u8>::new());
    }
}
