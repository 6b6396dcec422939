//! Values that remember where they were written in the rule file.
//!
//! TOML reports byte spans through `serde_spanned`'s protocol; the RON
//! deserializer has no such protocol, so in RON mode a [`Spanned`] carries
//! no span and diagnostics fall back to finding the literal in the source
//! (see [`super::diagnostic`]). The format is chosen by a thread-local that
//! [`with_format`] sets around one deserialization.

use std::cell::Cell;
use std::ops::Range;

use serde::{Deserialize, Deserializer};

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum SourceFormat {
    Toml,
    Ron,
}

thread_local! {
    static FORMAT: Cell<SourceFormat> = const { Cell::new(SourceFormat::Toml) };
}

/// Runs `f` (a deserialization) with `format` as the span protocol.
pub fn with_format<R>(format: SourceFormat, f: impl FnOnce() -> R) -> R {
    let previous = FORMAT.with(|c| c.replace(format));
    let result = f();
    FORMAT.with(|c| c.set(previous));
    result
}

/// A value with the byte range it came from, when the format provides one.
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
        match FORMAT.with(Cell::get) {
            SourceFormat::Toml => {
                let spanned = serde_spanned::Spanned::<T>::deserialize(deserializer)?;
                let span = spanned.span();
                Ok(Spanned {
                    value: spanned.into_inner(),
                    span: Some(span),
                })
            }
            SourceFormat::Ron => Ok(Spanned {
                value: T::deserialize(deserializer)?,
                span: None,
            }),
        }
    }
}
