//! Values that remember where they were written in the rule file.
//!
//! Both readers speak `serde_spanned`'s protocol: the TOML deserializer
//! natively, the RON one through [`super::ron`]'s span-preserving tree. So a
//! [`Spanned`] deserialized from either format carries the byte range of
//! its value (string spans include the quotes).

use std::ops::Range;

use serde::{Deserialize, Deserializer};

/// The two rule-file formats, chosen by extension.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum SourceFormat {
    Toml,
    Ron,
}

/// A value with the byte range it came from (`None` only for values made
/// by the program, such as a compound call written as a bare name).
#[derive(Clone, Debug, PartialEq)]
pub struct Spanned<T> {
    pub value: T,
    pub span: Option<Range<usize>>,
}

impl<T> Spanned<T> {
    pub fn new(value: T) -> Self {
        Self { value, span: None }
    }
}

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Spanned<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let spanned = serde_spanned::Spanned::<T>::deserialize(deserializer)?;
        let span = spanned.span();
        Ok(Spanned {
            value: spanned.into_inner(),
            span: Some(span),
        })
    }
}
