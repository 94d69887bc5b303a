//! The rows of a CSV table with their file lines: the reader settings shared by every table,
//! the sequential reader, the parallel row parser of large files, and the line of each row.

use std::path::Path;

use rayon::prelude::*;

use crate::error::{IoError, csv_error};

/// The CSV reader of every table: `#` comments, fields trimmed, one field count.
pub(crate) fn table_reader(text: &[u8]) -> csv::Reader<&[u8]> {
    csv::ReaderBuilder::new().comment(Some(b'#')).trim(csv::Trim::All).flexible(false).from_reader(text)
}

/// The data rows of `rdr` (its header already read) with their line numbers, all-empty rows
/// skipped.
pub(crate) fn sequential_rows(
    rdr: &mut csv::Reader<&[u8]>,
    path: &Path,
) -> Result<Vec<(u64, csv::StringRecord)>, IoError> {
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| csv_error(path, &e))?;
        if rec.iter().all(|f| f.is_empty()) {
            continue;
        }
        let line = rec.position().map_or(0, |p| p.line());
        rows.push((line, rec));
    }
    Ok(rows)
}

/// Moves every row's line to the line its record is on. The csv crate reports the line where
/// its reader started reading the record, before the empty and comment lines it skipped, so a
/// row after a blank line or a `#` line was named by the skipped line (one line early per
/// skipped line): each row goes to the first line at or after the reported one that is neither
/// empty nor a comment.
pub(crate) fn record_lines(text: &[u8], rows: &mut [(u64, csv::StringRecord)]) {
    let starts: Vec<usize> = std::iter::once(0)
        .chain(text.iter().enumerate().filter(|(_, b)| **b == b'\n').map(|(i, _)| i + 1))
        .collect();
    let line_text = |line: u64| -> Option<&[u8]> {
        let k = usize::try_from(line).ok()?.checked_sub(1)?;
        let start = *starts.get(k)?;
        let end = starts.get(k + 1).map_or(text.len(), |e| e - 1);
        text.get(start..end)
    };
    for (line, _) in rows.iter_mut() {
        while let Some(t) = line_text(*line) {
            let t = t.strip_suffix(b"\r").unwrap_or(t);
            if t.is_empty() || t.starts_with(b"#") {
                *line += 1;
            } else {
                break;
            }
        }
    }
}

/// Bytes of CSV text per task of [`parallel_rows`] (fixed, so the work split does not depend
/// on the number of threads; the result never does).
const PARSE_CHUNK: usize = 1 << 17;

/// The data rows after the header (`after_header`: the reader's position after it), parsed
/// in parallel over line-aligned chunks of `text` with the reader settings of
/// [`Table::read_checked`]: the same `(line, record)` rows, in order, as its sequential loop.
/// `None` (use the sequential reader) when the text has a quote or a carriage return (a
/// record could then span lines or line ends differ) or when any row is not well-formed
/// (unequal field count, invalid UTF-8): the sequential reader reports those exactly as
/// before.
pub(crate) fn parallel_rows(
    text: &[u8],
    after_header: &csv::Position,
    fields: usize,
) -> Option<Vec<(u64, csv::StringRecord)>> {
    let rest = text.get(usize::try_from(after_header.byte()).ok()?..)?;
    // line-aligned chunks: each ends just after a '\n' (the last one at the end of the text)
    let mut chunks = Vec::with_capacity(rest.len() / PARSE_CHUNK + 1);
    let mut start = 0;
    while start < rest.len() {
        let end = match rest.get(start + PARSE_CHUNK..).and_then(|t| t.iter().position(|b| *b == b'\n')) {
            Some(k) => start + PARSE_CHUNK + k + 1,
            None => rest.len(),
        };
        chunks.push((start, &rest[start..end]));
        start = end;
    }
    // per chunk: its rows with chunk-local positions, its records (incl. all-empty ones) and
    // its line ends
    type Part = (Vec<csv::StringRecord>, u64, u64);
    let parts: Vec<Option<Part>> = chunks
        .par_iter()
        .map(|(_, chunk)| {
            // one branch-free pass (vectorised): line ends, quotes or carriage returns, and the
            // other whitespace a field could be trimmed of
            let (line_ends, unusual, blanks) = chunk.iter().fold((0u64, 0u64, 0u64), |(n, u, w), b| {
                (
                    n + u64::from(*b == b'\n'),
                    u + u64::from(*b == b'"' || *b == b'\r'),
                    w + u64::from(*b == b' ' || *b == b'\t' || *b == b'\x0c'),
                )
            });
            if unusual > 0 {
                return None;
            }
            // without whitespace in the chunk trimming changes nothing: skip its per-record cost
            let trim = if blanks > 0 { csv::Trim::All } else { csv::Trim::None };
            let mut rdr = csv::ReaderBuilder::new()
                .has_headers(false)
                .comment(Some(b'#'))
                .trim(trim)
                .flexible(true)
                .from_reader(*chunk);
            let (mut rows, mut records) = (Vec::with_capacity(line_ends as usize + 1), 0);
            for rec in rdr.records() {
                let rec = rec.ok()?;
                if rec.len() != fields {
                    return None;
                }
                records += 1;
                if !rec.iter().all(|f| f.is_empty()) {
                    rows.push(rec);
                }
            }
            Some((rows, records, line_ends))
        })
        .collect();
    // chunk-local positions -> file positions (as the sequential reader would report them)
    let mut rows = Vec::with_capacity(parts.iter().flatten().map(|p| p.0.len()).sum());
    let (mut line, mut record) = (after_header.line(), after_header.record());
    for ((offset, _), part) in chunks.iter().zip(parts) {
        let (part_rows, records, line_ends) = part?;
        for mut rec in part_rows {
            let local = rec.position().cloned().unwrap_or_else(csv::Position::new);
            let mut pos = csv::Position::new();
            pos.set_byte(after_header.byte() + *offset as u64 + local.byte())
                .set_line(line + local.line() - 1)
                .set_record(record + local.record());
            rec.set_position(Some(pos.clone()));
            rows.push((pos.line(), rec));
        }
        line += line_ends;
        record += records;
    }
    Some(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The parallel row parser gives the sequential reader's rows (fields, line numbers,
    /// positions) on a large file with comments, blank lines, all-empty rows and padded
    /// fields, and declines (so that the sequential reader words the error) on quotes,
    /// carriage returns and rows with the wrong field count.
    #[test]
    fn parallel_rows_equal_the_sequential_reader() {
        let mut text = String::from("# candidates\n\n a , b ,c\n");
        for k in 0..30_000 {
            match k % 997 {
                3 => text.push_str("# a comment line\n"),
                5 => text.push('\n'),
                7 => text.push_str(",,\n"),
                11 => text.push_str("  \t\n"),
                _ => {}
            }
            text.push_str(&format!("{k}, {} ,x{}\n", k as f64 * 0.25, k % 7));
        }
        text.push_str("last,1,2"); // no final line end
        let sequential = |t: &str| {
            let mut rdr = table_reader(t.as_bytes());
            rdr.headers().expect("header");
            sequential_rows(&mut rdr, Path::new("x.csv"))
        };
        let parallel = |t: &str| {
            let mut rdr = table_reader(t.as_bytes());
            let fields = rdr.headers().expect("header").len();
            parallel_rows(t.as_bytes(), rdr.position(), fields)
        };
        // a line of blanks is a one-field record: the sequential reader rejects it...
        assert!(sequential(&text).is_err());
        assert!(parallel(&text).is_none());
        let text = text.replace("  \t\n", "");
        let want = sequential(&text).expect("sequential");
        let got = parallel(&text).expect("parallel");
        assert!(text.len() > 3 * PARSE_CHUNK, "the file spans several chunks");
        assert_eq!(got.len(), want.len());
        for ((gl, gr), (wl, wr)) in got.iter().zip(&want) {
            assert_eq!((gl, gr), (wl, wr));
            assert_eq!(gr.position(), wr.position(), "line {wl}");
        }
        // quotes and carriage returns go to the sequential reader
        assert!(parallel(&text.replacen("x3", "\"x3\"", 1)).is_none());
        assert!(parallel(&text.replacen("x3\n", "x3\r\n", 1)).is_none());
        assert!(parallel(&text.replacen("x3\n", "x3,extra\n", 1)).is_none());
    }
}
