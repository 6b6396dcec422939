//! Loading a rule file: its bytes as UTF-8 text (a bad byte located),
//! its format by extension, and the spanned syntax tree; `--set`
//! overrides as typed.

use super::*;

/// A `--set name=value` override from the command line.
#[derive(Debug, Clone, PartialEq)]
pub struct Override {
    pub name: String,
    pub value: String,
}

impl Override {
    /// Parses `name=value`.
    pub fn parse(text: &str) -> Result<Override, String> {
        let (name, value) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}` is not of the form name=value"))?;
        let name = name.trim();
        if name.is_empty() || value.trim().is_empty() {
            return Err(format!("`{text}` is not of the form name=value"));
        }
        Ok(Override {
            name: name.to_owned(),
            value: value.trim().to_owned(),
        })
    }
}

/// A rule file's text from its bytes; bytes that are not UTF-8 are an
/// error located at the first bad byte.
pub fn source_from_bytes(name: String, bytes: Vec<u8>) -> Result<SourceFile, RuleError> {
    match String::from_utf8(bytes) {
        Ok(text) => Ok(SourceFile { name, text }),
        Err(err) => {
            let offset = err.utf8_error().valid_up_to();
            let bad = err.as_bytes()[offset];
            // Show the text up to the bad byte, so the snippet is exact.
            let text = String::from_utf8_lossy(&err.as_bytes()[..offset]).into_owned();
            let file = SourceFile { name, text };
            Err(RuleError::at(
                &file,
                Some(offset..offset),
                format!(
                    "the rule file is not UTF-8 text: byte 0x{bad:02x} at byte offset {offset}"
                ),
            )
            .with_label("the bad byte is here")
            .with_help("save the file as UTF-8"))
        }
    }
}

/// Parses a rule file's text, in the format its name's extension says.
pub fn load(file: &SourceFile) -> Result<RuleFile, RuleError> {
    let format = format_of(Path::new(&file.name)).map_err(|m| RuleError::at(file, None, m))?;
    parse(file, format)
}

/// The rule format for a path's extension.
pub fn format_of(path: &Path) -> Result<SourceFormat, String> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("toml") => Ok(SourceFormat::Toml),
        Some("ron") => Ok(SourceFormat::Ron),
        _ => Err("rule files must end in .toml or .ron".to_owned()),
    }
}

/// Parses rule text in the given format.
pub fn parse(file: &SourceFile, format: SourceFormat) -> Result<RuleFile, RuleError> {
    match format {
        SourceFormat::Toml => toml::from_str::<RuleFile>(&file.text)
            .map_err(|err| RuleError::at(file, err.span(), err.message().trim().to_owned())),
        SourceFormat::Ron => crate::rules::ron::parse(&file.text)
            .and_then(|value| crate::rules::ron::from_value::<RuleFile>(&value))
            .map_err(|err| RuleError::at(file, err.span, err.message)),
    }
}
