//! Metadata recorded in a CSV file's comment lines: `# vatcal-<name>: key=value key=value`.
//!
//! Every table reader skips `#` lines, so metadata never changes what a file's rows mean; a
//! reader that wants it asks for it with [`read_metadata`]. One kind exists:
//!
//! * `# vatcal-noise: probe_sigma_mm=0.002 tracker_sigma_mm=0.0067 orientation_sigma_mrad=1` —
//!   the measuring instruments' noise, σ per axis of one probe row / one tracker row \[mm\] and
//!   of the rotation of one pose row \[mrad\] (any key may be left out). `vatcal campaign` writes it from the devices file's `[noise]` table;
//!   `vatcal discover` uses it as the noise reference of its size rule when no replicate
//!   measurements are in the data (flags given on the command line take precedence).
//!
//! The line may stand anywhere in the file (before the header is usual). A `# vatcal-noise:`
//! line with an unknown key, a value that is not a positive number, or a key given twice is an
//! error naming the file, the line and the key ([`IoError::Row`]); other comment lines,
//! including other `# vatcal-…:` kinds, are ignored. See `docs/formats.md`.

use std::path::Path;

use crate::IoError;

/// Prefix of a noise metadata line (after `#` and optional spaces).
pub const NOISE_TAG: &str = "vatcal-noise:";

/// The instruments' noise recorded in a measurement file (`# vatcal-noise: ...`).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NoiseMetadata {
    /// σ per axis of one probe row \[mm\]
    pub probe_sigma_mm: Option<f64>,
    /// σ per axis of one tracker row \[mm\]
    pub tracker_sigma_mm: Option<f64>,
    /// σ per axis of the rotation of one pose row (its rotation-vector residual) \[mrad\]
    pub orientation_sigma_mrad: Option<f64>,
}

impl NoiseMetadata {
    /// True when no sigma is given.
    pub fn is_empty(&self) -> bool {
        self.probe_sigma_mm.is_none()
            && self.tracker_sigma_mm.is_none()
            && self.orientation_sigma_mrad.is_none()
    }

    /// The comment line (with `#` and a trailing newline) that records this noise; empty when
    /// nothing is known.
    pub fn header_line(&self) -> String {
        let mut fields = Vec::new();
        if let Some(s) = self.probe_sigma_mm {
            fields.push(format!("probe_sigma_mm={s}"));
        }
        if let Some(s) = self.tracker_sigma_mm {
            fields.push(format!("tracker_sigma_mm={s}"));
        }
        if let Some(s) = self.orientation_sigma_mrad {
            fields.push(format!("orientation_sigma_mrad={s}"));
        }
        if fields.is_empty() { String::new() } else { format!("# {NOISE_TAG} {}\n", fields.join(" ")) }
    }
}

/// Everything recorded in a file's metadata comment lines.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Metadata {
    /// the instruments' noise, when recorded
    pub noise: Option<NoiseMetadata>,
}

/// Reads the metadata comment lines of a CSV file (see the module docs).
///
/// # Examples
/// ```
/// use vatcal_io::metadata::{NoiseMetadata, read_metadata};
///
/// let path = std::env::temp_dir().join(format!("vatcal-meta-doc-{}.csv", std::process::id()));
/// std::fs::write(&path, "# vatcal-noise: probe_sigma_mm=0.003\nposition,tcp,q1\n")?;
/// let meta = read_metadata(&path);
/// std::fs::remove_file(&path)?;
/// assert_eq!(meta?.noise, Some(NoiseMetadata { probe_sigma_mm: Some(0.003), ..NoiseMetadata::default() }));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// [`IoError::File`] when the file cannot be read; [`IoError::Row`] for a malformed metadata
/// line (file, line, key and reason).
pub fn read_metadata(path: impl AsRef<Path>) -> Result<Metadata, IoError> {
    let path = path.as_ref();
    let text = std::fs::read(path).map_err(|source| IoError::File { path: path.into(), cause: source })?;
    parse_metadata(path, &String::from_utf8_lossy(&text))
}

/// [`read_metadata`] on text already in memory (`path` names it in errors).
///
/// # Errors
/// As [`read_metadata`].
pub fn parse_metadata(path: &Path, text: &str) -> Result<Metadata, IoError> {
    let mut meta = Metadata::default();
    for (k, line) in text.lines().enumerate() {
        let Some(comment) = line.trim_start().strip_prefix('#') else { continue };
        let Some(rest) = comment.trim_start().strip_prefix(NOISE_TAG) else { continue };
        let row = |column: &str, reason: String| IoError::Row {
            path: path.into(),
            line: k as u64 + 1,
            column: column.to_string(),
            reason,
        };
        let noise = meta.noise.get_or_insert_with(NoiseMetadata::default);
        for field in rest.split_whitespace() {
            let (key, value) = field
                .split_once('=')
                .ok_or_else(|| row(field, "expected key=value (e.g. probe_sigma_mm=0.002)".into()))?;
            let slot = match key {
                "probe_sigma_mm" => &mut noise.probe_sigma_mm,
                "tracker_sigma_mm" => &mut noise.tracker_sigma_mm,
                "orientation_sigma_mrad" => &mut noise.orientation_sigma_mrad,
                _ => {
                    return Err(row(
                        key,
                        "unknown key (known: probe_sigma_mm, tracker_sigma_mm, orientation_sigma_mrad)"
                            .into(),
                    ));
                }
            };
            let v: f64 = value.parse().map_err(|_| row(key, format!("`{value}` is not a number")))?;
            if !(v.is_finite() && v > 0.0) {
                let unit = if key.ends_with("_mrad") { "mrad" } else { "mm" };
                return Err(row(key, format!("must be a positive number of {unit}, got {value}")));
            }
            if slot.is_some() {
                return Err(row(key, "given twice".into()));
            }
            *slot = Some(v);
        }
    }
    if meta.noise.is_some_and(|n| n.is_empty()) {
        meta.noise = None;
    }
    Ok(meta)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Metadata, IoError> {
        parse_metadata(Path::new("m.csv"), text)
    }

    #[test]
    fn noise_line_round_trips_and_other_comments_are_ignored() {
        let n = NoiseMetadata {
            probe_sigma_mm: Some(0.002),
            tracker_sigma_mm: Some(0.0067),
            orientation_sigma_mrad: Some(0.5),
        };
        let text = format!("# a comment\n{}position,tcp\n# vatcal-other: x=1\n", n.header_line());
        assert_eq!(parse(&text).expect("parses").noise, Some(n));
        assert_eq!(parse("position,tcp\n1,2\n").expect("parses").noise, None);
        assert_eq!(NoiseMetadata::default().header_line(), "");
        let probe_only = NoiseMetadata { probe_sigma_mm: Some(0.003), ..NoiseMetadata::default() };
        assert_eq!(probe_only.header_line(), "# vatcal-noise: probe_sigma_mm=0.003\n");
    }

    #[test]
    fn bad_noise_lines_name_line_and_key() {
        for (text, key, why) in [
            ("x\n# vatcal-noise: probe_sigma=0.1\n", "probe_sigma", "unknown key"),
            ("# vatcal-noise: probe_sigma_mm=abc\n", "probe_sigma_mm", "not a number"),
            ("# vatcal-noise: tracker_sigma_mm=-1\n", "tracker_sigma_mm", "positive"),
            (
                "# vatcal-noise: orientation_sigma_mrad=0\n",
                "orientation_sigma_mrad",
                "positive number of mrad",
            ),
            ("# vatcal-noise: probe_sigma_mm=1 probe_sigma_mm=2\n", "probe_sigma_mm", "twice"),
            ("# vatcal-noise: 0.002\n", "0.002", "key=value"),
        ] {
            let e = parse(text).expect_err(text).to_string();
            assert!(e.contains(&format!("`{key}`")) && e.contains(why), "{e}");
            let line = if text.starts_with("x\n") { "m.csv:2:" } else { "m.csv:1:" };
            assert!(e.starts_with(line), "{e}");
        }
    }
}
