//! Several markers of one body (issue 31): TCP ids the measurement rows use that the cell file
//! lacks are unknown TCPs, fitted like the others once `--unknown-tcps` lists (or confirms) them
//! (`vatcal identify`, `vatcal discover`); `vatcal validate` reads the calibrated cell, which
//! contains them.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::bail;
use vatcal_core::cell::PointEntry;
use vatcal_core::{Axis, CellFile, Measurement, ParamId};
use vatcal_identification::Identification;
use vatcal_io::RowSource;
use vatcal_kinematics::Model;

/// What `--unknown-tcps` resolved to.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct UnknownTcps {
    /// TCP ids added to the cell (at the placeholder), ascending
    pub added: Vec<u32>,
    /// the placeholder offset the added TCPs start from \[mm, frame N\] and where it came from
    pub placeholder: ([f64; 3], String),
}

impl UnknownTcps {
    /// One line for the terminal (nothing when the flag added nothing).
    pub fn describe(&self) -> Option<String> {
        (!self.added.is_empty()).then(|| {
            format!(
                "unknown markers: tcp {} added at the placeholder ({:.3}, {:.3}, {:.3}) mm ({}); the initialisation solves them, the fit identifies them",
                join(&self.added),
                self.placeholder.0[0],
                self.placeholder.0[1],
                self.placeholder.0[2],
                self.placeholder.1
            )
        })
    }
}

fn join(ids: &[u32]) -> String {
    ids.iter().map(u32::to_string).collect::<Vec<_>>().join(",")
}

/// The TCP ids the rows use that `known` lacks, ascending, each with the index of its first row.
pub fn missing_tcps(rows: &[Measurement], known: &[u32]) -> Vec<(u32, usize)> {
    let mut first: BTreeMap<u32, usize> = BTreeMap::new();
    for (k, m) in rows.iter().enumerate() {
        if !known.contains(&m.tcp) {
            first.entry(m.tcp).or_insert(k);
        }
    }
    first.into_iter().collect()
}

/// The TCP ids the rows use, ascending.
pub fn used_tcps(rows: &[Measurement]) -> Vec<u32> {
    let mut ids: Vec<u32> = rows.iter().map(|m| m.tcp).collect();
    ids.sort_unstable();
    ids.dedup();
    ids
}

/// Where row `k` came from, for messages.
fn row_name(sources: &[RowSource], k: usize) -> String {
    sources.get(k).map_or_else(|| format!("row {}", k + 1), ToString::to_string)
}

/// [`add_unknown_tcps`] for a command: resolves `--unknown-tcps` against the rows, prints what
/// it did, and returns the model rebuilt from the cell when markers were added (`model` as it
/// was otherwise) with what the flag resolved to. `model_path` names the cell file in errors.
pub fn model_with_unknown_tcps(
    cell: &mut CellFile,
    model: Model,
    model_path: &Path,
    spec: Option<&str>,
    rows: &[Measurement],
    sources: &[RowSource],
) -> anyhow::Result<(Model, UnknownTcps)> {
    let markers = add_unknown_tcps(cell, model_path, spec, rows, sources)?;
    if let Some(line) = markers.describe() {
        println!("{line}");
    }
    if markers.added.is_empty() {
        return Ok((model, markers));
    }
    let model = super::model_of(cell, model_path)?;
    Ok((model, markers))
}

/// Resolves `--unknown-tcps` (`flag` names it in messages) against the rows and adds the TCPs
/// the rows use that the cell lacks, at the placeholder (TCP 1's offset, else the first TCP's,
/// else the flange origin). Without the flag such rows are an error naming the first row and the
/// flag to pass; a listed id no row uses is an error; a listed id the cell file has (given both
/// as known and as unknown) is an error naming its `[[tcps]]` entry in `cell_path` by line and
/// column ([`known_and_unknown`]).
pub fn add_unknown_tcps(
    cell: &mut CellFile,
    cell_path: &Path,
    spec: Option<&str>,
    rows: &[Measurement],
    sources: &[RowSource],
) -> anyhow::Result<UnknownTcps> {
    let known: Vec<u32> = cell.tcps.iter().map(|t| t.id).collect();
    let missing = missing_tcps(rows, &known);
    let missing_ids: Vec<u32> = missing.iter().map(|(id, _)| *id).collect();
    let listed = match spec.map(str::trim) {
        None => match missing.first() {
            Some(&(id, row)) => bail!(
                "{}: column `tcp`: unknown tcp id {id} (the model has {known:?}); the rows use TCP id(s) {} that the cell file lacks: pass `--unknown-tcps {}` (or `--unknown-tcps all`) to fit them as markers at unknown offsets",
                row_name(sources, row),
                join(&missing_ids),
                join(&missing_ids)
            ),
            None => return Ok(UnknownTcps::default()),
        },
        Some("all") => missing_ids.clone(),
        Some(text) => parse_ids(text)?,
    };
    let conflicts: Vec<u32> = listed.iter().copied().filter(|id| known.contains(id)).collect();
    if !conflicts.is_empty() {
        bail!("{}", known_and_unknown(cell_path, &conflicts, &listed));
    }
    let used = used_tcps(rows);
    for id in &listed {
        if !used.contains(id) {
            bail!("--unknown-tcps: no row uses tcp {id} (the rows use tcp {})", join(&used));
        }
    }
    if let Some(&(id, row)) = missing.iter().find(|(id, _)| !listed.contains(id)) {
        let mut all = listed.clone();
        all.extend(missing_ids.iter().filter(|m| !listed.contains(m)));
        all.sort_unstable();
        all.dedup();
        bail!(
            "{}: column `tcp`: unknown tcp id {id} (the model has {known:?}, --unknown-tcps lists {}): pass `--unknown-tcps {}` (or `all`)",
            row_name(sources, row),
            join(&listed),
            join(&all)
        );
    }
    let placeholder = match cell.tcps.iter().find(|t| t.id == 1).or_else(|| cell.tcps.first()) {
        Some(t) => ([t.x_mm, t.y_mm, t.z_mm], format!("the cell's tcp {}", t.id)),
        None => ([0.0; 3], "the flange origin".to_string()),
    };
    let mut added = listed;
    added.sort_unstable();
    added.dedup();
    let out = UnknownTcps { added, placeholder };
    let [x_mm, y_mm, z_mm] = out.placeholder.0;
    for id in &out.added {
        cell.tcps.push(PointEntry { id: *id, x_mm, y_mm, z_mm });
    }
    Ok(out)
}

/// The one-line error of TCP ids `conflicts` that `--unknown-tcps` lists (as `listed`) and the
/// cell file has: it names the first one's `[[tcps]]` entry as `file:line:column` (the column of
/// its `id` value), where the user either removes the entry (to fit the marker from the
/// placeholder) or drops the id from the flag (to fit it from its cell value). The file alone
/// when its text does not show the entry (e.g. an inline table).
fn known_and_unknown(cell_path: &Path, conflicts: &[u32], listed: &[u32]) -> String {
    let first = conflicts[0];
    let others =
        if conflicts.len() > 1 { format!(" (also tcp {})", join(&conflicts[1..])) } else { String::new() };
    format!(
        "{}: tcp {first} is given both as known (this [[tcps]] entry of the cell file) and as unknown (--unknown-tcps {}){others}: drop it from --unknown-tcps to fit it from its cell value, or remove the entry to fit it as a marker at an unknown offset",
        tcp_entry_location(cell_path, first),
        join(listed)
    )
}

/// `file:line:column` of the `id = {id}` key of a `[[tcps]]` entry of the cell file (the column
/// of the value), or the file alone when the text does not show it.
fn tcp_entry_location(cell_path: &Path, id: u32) -> String {
    let file = cell_path.display();
    let Ok(text) = std::fs::read_to_string(cell_path) else { return file.to_string() };
    let mut in_tcps = false;
    for (k, line) in text.lines().enumerate() {
        let code = line.split('#').next().unwrap_or("");
        let trimmed = code.trim();
        if trimmed.starts_with('[') {
            in_tcps = trimmed.split_whitespace().collect::<String>() == "[[tcps]]";
            continue;
        }
        let Some((key, value)) = code.split_once('=') else { continue };
        if !in_tcps || key.trim() != "id" || value.trim().parse::<u32>() != Ok(id) {
            continue;
        }
        let at = key.len() + 1 + (value.len() - value.trim_start().len());
        return format!("{file}:{}:{}", k + 1, code[..at].chars().count() + 1);
    }
    file.to_string()
}

/// `--unknown-tcps 2,3,4`: the ids (at least one, each a non-negative integer).
fn parse_ids(text: &str) -> anyhow::Result<Vec<u32>> {
    // `split` yields at least one piece: an empty list has to be caught before it
    if text.is_empty() {
        bail!("--unknown-tcps: no TCP ids given (expected ids like 2,3,4 or `all`)");
    }
    text.split(',')
        .map(|s| {
            s.trim().parse::<u32>().map_err(|_| {
                anyhow::anyhow!(
                    "--unknown-tcps: `{}` is not a TCP id (expected ids like 2,3,4 or `all`)",
                    s.trim()
                )
            })
        })
        .collect()
}

/// The markers of a fit, one line each: every TCP the rows use, its offset in frame N and the
/// standard deviation of each coordinate (or why it has none), and where it started from.
pub fn marker_lines(fit: &Identification, rows: &[Measurement], unknown: &UnknownTcps) -> Vec<String> {
    used_tcps(rows)
        .into_iter()
        .map(|id| {
            let origin = if unknown.added.contains(&id) { "unknown (--unknown-tcps)" } else { "cell file" };
            let Some(v) = fit.model.tcp(id) else { return format!("  tcp {id}: not in the model") };
            let sigma: Vec<Option<f64>> = Axis::ALL
                .iter()
                .map(|&axis| fit.params.index_of(ParamId::Tcp { id, axis }).map(|k| fit.sigma[k]))
                .collect();
            let coords: Vec<String> = Axis::ALL
                .iter()
                .zip(&sigma)
                .map(|(axis, s)| {
                    let value = v[axis.index()];
                    match s {
                        Some(s) => format!("{} {value:.4} ± {s:.4}", axis.letter()),
                        None => format!("{} {value:.4} (not fitted)", axis.letter()),
                    }
                })
                .collect();
            format!("  tcp {id}: {} mm [{origin}]", coords.join(", "))
        })
        .collect()
}

/// The TCPs added by `--unknown-tcps` that the fitted set left out (they stay at the
/// placeholder): a warning each.
pub fn unfitted(fit: &Identification, unknown: &UnknownTcps) -> Vec<u32> {
    unknown
        .added
        .iter()
        .copied()
        .filter(|&id| Axis::ALL.iter().all(|&axis| fit.params.index_of(ParamId::Tcp { id, axis }).is_none()))
        .collect()
}

/// A model with the TCPs of `from` that `model` lacks and the rows use (a baseline cell without
/// the markers, validated on rows of every marker): returns the ids copied.
pub fn copy_missing_tcps(model_cell: &mut CellFile, from: &Model, rows: &[Measurement]) -> Vec<u32> {
    let known: Vec<u32> = model_cell.tcps.iter().map(|t| t.id).collect();
    let mut copied = Vec::new();
    for (id, _) in missing_tcps(rows, &known) {
        if let Some(v) = from.tcp(id) {
            model_cell.tcps.push(PointEntry { id, x_mm: v.x, y_mm: v.y, z_mm: v.z });
            copied.push(id);
        }
    }
    copied
}
