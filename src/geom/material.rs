//! Materials as the writers need them: PBR metallic-roughness (glTF 2.0
//! §3.9.2), format-neutral. Colours are linear RGB, as glTF stores its
//! factors; rule files write sRGB hex (`"#c8a27a"`), converted once by
//! [`srgb_to_linear`].

/// How a material's alpha is used (glTF `alphaMode`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AlphaMode {
    Opaque,
    /// Alpha below the cutoff is fully transparent, at or above it opaque.
    Mask(f64),
    Blend,
}

/// One material.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Unique within a mesh (ASCII letters, digits, `_`, `-`, `.`).
    pub name: String,
    /// Linear RGB and alpha, each in [0, 1].
    pub base_color: [f64; 4],
    pub metallic: f64,
    pub roughness: f64,
    /// Linear RGB in [0, 1].
    pub emissive: [f64; 3],
    pub alpha: AlphaMode,
    /// `None`: decided when the mesh is finished
    /// ([`crate::geom::IndexedMesh::decide_double_sided`]): double-sided
    /// unless every polygon using it lies on closed shells, so open
    /// sheets (blades, leaves, flags) are seen from behind.
    pub double_sided: Option<bool>,
}

impl Material {
    /// The material of everything that names none: a light warm grey,
    /// dielectric, fairly rough (what an artist's default cube looks like).
    pub fn fallback() -> Material {
        Material {
            name: "graftal_default".into(),
            base_color: [0.6, 0.6, 0.58, 1.0],
            metallic: 0.0,
            roughness: 0.6,
            emissive: [0.0; 3],
            alpha: AlphaMode::Opaque,
            double_sided: None,
        }
    }

    /// Whether `name` can be written into OBJ's `.mtl` and glTF as it is.
    pub fn valid_name(name: &str) -> bool {
        !name.is_empty()
            && name.len() <= 64
            && name
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'_' | b'-' | b'.'))
    }
}

/// `name` made valid for [`Material::valid_name`] (and part names):
/// other characters become `_`, cut to 64 bytes; `fallback` when empty.
pub fn sanitize_name(name: &str, fallback: &str) -> String {
    let clean: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.') {
                c
            } else {
                '_'
            }
        })
        .take(64)
        .collect();
    if clean.is_empty() {
        fallback.to_owned()
    } else {
        clean
    }
}

/// Makes names unique by suffixing repeats (`wood`, `wood.1`, …), keeping
/// each within 64 bytes.
pub fn dedupe_names(names: &mut [String]) {
    for i in 1..names.len() {
        let base = names[i].clone();
        let mut n = 1;
        while names[..i].contains(&names[i]) {
            let suffix = format!(".{n}");
            let keep = base.len().min(64 - suffix.len());
            names[i] = format!("{}{suffix}", &base[..keep]);
            n += 1;
        }
    }
}

/// sRGB transfer function inverse (IEC 61966-2-1), component in [0, 1].
pub fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        libm::pow((c + 0.055) / 1.055, 2.4)
    }
}

/// sRGB transfer function (IEC 61966-2-1), component in [0, 1].
pub fn linear_to_srgb(c: f64) -> f64 {
    if c <= 0.0031308 {
        c * 12.92
    } else {
        1.055 * libm::pow(c, 1.0 / 2.4) - 0.055
    }
}

/// Parses `#rgb`, `#rrggbb` or `#rrggbbaa` (sRGB) into linear RGBA.
pub fn parse_hex_color(text: &str) -> Option<[f64; 4]> {
    let hex = text.strip_prefix('#')?;
    if !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
        return None;
    }
    let digit = |i: usize| u8::from_str_radix(&hex[i..i + 1], 16).ok();
    let pair = |i: usize| u8::from_str_radix(&hex[i..i + 2], 16).ok();
    let bytes: Vec<u8> = match hex.len() {
        3 => (0..3)
            .map(|i| digit(i).map(|d| d * 17))
            .collect::<Option<_>>()?,
        6 | 8 => (0..hex.len() / 2)
            .map(|i| pair(2 * i))
            .collect::<Option<_>>()?,
        _ => return None,
    };
    let unit = |b: u8| f64::from(b) / 255.0;
    Some([
        srgb_to_linear(unit(bytes[0])),
        srgb_to_linear(unit(bytes[1])),
        srgb_to_linear(unit(bytes[2])),
        // Alpha is not gamma-encoded.
        bytes.get(3).map_or(1.0, |&a| unit(a)),
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hex_colours_are_srgb() {
        let c = parse_hex_color("#ffffff").unwrap();
        assert_eq!(c, [1.0, 1.0, 1.0, 1.0]);
        let grey = parse_hex_color("#808080").unwrap();
        // sRGB 128 is linear 0.2158605…
        assert!((grey[0] - 0.215_860_500_9).abs() < 1e-9, "{grey:?}");
        assert_eq!(parse_hex_color("#f00").unwrap()[..3], [1.0, 0.0, 0.0]);
        assert_eq!(parse_hex_color("#00000080").unwrap()[3], 128.0 / 255.0);
        for bad in ["fff", "#ff", "#ggg", "#12345", "#1234567", "#ééé"] {
            assert_eq!(parse_hex_color(bad), None, "{bad}");
        }
    }

    #[test]
    fn transfer_functions_invert() {
        for i in 0..=100 {
            let c = f64::from(i) / 100.0;
            assert!((linear_to_srgb(srgb_to_linear(c)) - c).abs() < 1e-12);
        }
    }
}
