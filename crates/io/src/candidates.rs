//! Candidate poses `position,tcp,q1..qN` (and plane rows `plane,tcp,q1..qN[,normal]`, tracker
//! rows `tcp,q1..qN,x,y,z`): read with their raw rows, so a selection is written back with
//! exactly the input's columns.

use std::path::Path;

use vatcal_core::Measurement;
use vatcal_kinematics::Model;

use crate::columns::required_columns;
use crate::error::{IoError, csv_error};
use crate::table::{RowIds, Table};
use crate::write::writer;

/// A candidate-pose table: the parsed measurements plus the raw rows, so a selection can be
/// written back with exactly the input's columns.
#[derive(Debug, Clone)]
pub struct CandidateTable {
    /// the header of the input
    pub headers: csv::StringRecord,
    /// the raw rows, in input order
    pub records: Vec<csv::StringRecord>,
    /// 1-based line numbers of the rows
    pub lines: Vec<u64>,
    /// the candidates as measurements: probe rows (the target is the calibration position),
    /// plane rows (the contact plane, any id: planes the cell lacks are the caller's to add)
    /// and tracker rows (their `x,y,z` do not enter a selection)
    pub measurements: Vec<Measurement>,
}

/// Reads candidate poses `position,tcp,q1..qN` (other columns kept verbatim). A row with a
/// non-empty `plane` is a plane contact (`plane,tcp,q1..qN[,normal]`, as
/// [`read_measurements`](crate::read_measurements) reads it), a row with neither `position` nor
/// `plane` but `x,y,z` a tracker row; the kinds may be mixed in one file.
///
/// # Examples
/// Read candidates, keep two and write them back with the input's columns:
/// ```
/// use vatcal_core::CellFile;
/// use vatcal_io::read_candidates;
/// use vatcal_kinematics::Model;
///
/// let model = Model::from_cell(&CellFile::load(concat!(env!("CARGO_MANIFEST_DIR"), "/../../fixtures/meca500-table.toml"))?)?;
/// let dir = std::env::temp_dir();
/// let (input, output) = (dir.join(format!("vatcal-doc-cand-{}.csv", std::process::id())), dir.join(format!("vatcal-doc-sel-{}.csv", std::process::id())));
/// std::fs::write(&input, "position,tcp,q1,q2,q3,q4,q5,q6,note\n1,1,0,0,0,0,0,0,a\n1,2,10,0,0,0,0,0,b\n1,3,20,0,0,0,0,0,c\n")?;
/// let table = read_candidates(&input, &model)?;
/// table.write_subset(&output, &[2, 0])?;
/// let text = std::fs::read_to_string(&output)?;
/// std::fs::remove_file(&input)?;
/// std::fs::remove_file(&output)?;
/// assert_eq!(table.measurements.len(), 3);
/// assert_eq!(text, "position,tcp,q1,q2,q3,q4,q5,q6,note\n1,3,20,0,0,0,0,0,c\n1,1,0,0,0,0,0,0,a\n");
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
/// As [`read_probe_measurements`](crate::read_probe_measurements) (without the check of the effects'
/// context columns); a header without `position`, `plane` and `x,y,z`; a row with both
/// `position` and `plane` or with none of the three.
pub fn read_candidates(path: impl AsRef<Path>, model: &Model) -> Result<CandidateTable, IoError> {
    let path = path.as_ref();
    let t = Table::read_for(path, model, &required_columns(&["tcp"], model, &[]))?;
    let has_xyz = t.has("x") && t.has("y") && t.has("z");
    if !t.has("position") && !t.has("plane") && !has_xyz {
        return Err(t.err(
            t.header_line,
            "position",
            "missing: candidate rows are probe rows (`position`), plane rows (`plane`, optional `normal`) or tracker rows (`x,y,z`)",
        ));
    }
    let ids = RowIds::of(model);
    let measurements = t.convert(|line, rec| {
        let filled = |c: &str| t.field(rec, c).is_some_and(|s| !s.is_empty());
        match (filled("position"), filled("plane")) {
            (true, true) => {
                Err(t.err(line, "plane", "a row is a probe row (`position`) or a plane row (`plane`), not both"))
            }
            (true, false) => t.probe_measurement(line, rec, model, &ids),
            (false, true) => t.plane_measurement(line, rec, model, &ids),
            (false, false) if has_xyz && filled("x") => t.tracker_measurement(line, rec, model, &ids),
            (false, false) => Err(t.err(
                line,
                if t.has("position") { "position" } else { "plane" },
                "empty: a candidate row needs `position` (probe), `plane` (plane contact) or `x,y,z` (tracker)",
            )),
        }
    })?;
    Ok(CandidateTable {
        headers: t.headers.clone(),
        lines: t.rows.iter().map(|r| r.0).collect(),
        records: t.rows.into_iter().map(|r| r.1).collect(),
        measurements,
    })
}

impl CandidateTable {
    /// Writes the rows at `indices` (in that order) with the input's header and columns.
    pub fn write_subset(&self, path: impl AsRef<Path>, indices: &[usize]) -> Result<(), IoError> {
        let path = path.as_ref();
        let mut w = writer(path)?;
        w.write_record(&self.headers).map_err(|e| csv_error(path, &e))?;
        for &i in indices {
            if let Some(rec) = self.records.get(i) {
                w.write_record(rec).map_err(|e| csv_error(path, &e))?;
            }
        }
        w.flush().map_err(|source| IoError::File { path: path.into(), cause: source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vatcal_core::Target;

    fn ur5e() -> Model {
        crate::tests::fixture_model("ur5e.toml")
    }

    fn read(text: &str) -> Result<CandidateTable, IoError> {
        let f = tempfile::NamedTempFile::new().expect("tmp");
        std::fs::write(f.path(), text).expect("write");
        read_candidates(f.path(), &ur5e())
    }

    /// Probe, plane (touched and pressed; a plane id the cell lacks) and tracker rows in one
    /// file; a selection keeps the input's columns.
    #[test]
    fn plane_and_tracker_rows_mix_with_probe_rows() {
        let head = "position,plane,tcp,q1,q2,q3,q4,q5,q6,normal,x,y,z,note\n";
        let t = read(&format!(
            "{head}1,,1,0,-90,90,0,90,0,,,,,a\n,7,1,0,-80,90,0,90,0,1,,,,b\n,7,2,10,-80,90,0,90,0,,,,,c\n,,1,0,-70,90,0,90,0,,1,2,3,d\n"
        ))
        .expect("mixed rows");
        let targets: Vec<Target> = t.measurements.iter().map(|m| m.target).collect();
        assert_eq!(targets[0], Target::Probe { position: 1 });
        assert_eq!(targets[1], Target::Plane { plane: 7, normal: true });
        assert_eq!(targets[2], Target::Plane { plane: 7, normal: false });
        assert!(matches!(targets[3], Target::Tracker { .. }));
        assert_eq!(vatcal_core::informative_rows(&t.measurements), 3 + 3 + 1 + 3);
        let out = tempfile::NamedTempFile::new().expect("tmp");
        t.write_subset(out.path(), &[2, 1]).expect("write");
        let text = std::fs::read_to_string(out.path()).expect("read");
        assert_eq!(text, format!("{head},7,2,10,-80,90,0,90,0,,,,,c\n,7,1,0,-80,90,0,90,0,1,,,,b\n"));
        // a plane-only file needs no `position` column
        let t = read("plane,tcp,q1,q2,q3,q4,q5,q6\n3,1,0,-90,90,0,90,0\n").expect("plane rows");
        assert_eq!(t.measurements[0].target, Target::Plane { plane: 3, normal: false });
    }

    #[test]
    fn bad_candidate_rows_name_line_and_column() {
        let e = read("tcp,q1,q2,q3,q4,q5,q6\n1,0,0,0,0,0,0\n").expect_err("no kind").to_string();
        assert!(e.contains("position") && e.contains("plane"), "{e}");
        let e =
            read("position,plane,tcp,q1,q2,q3,q4,q5,q6\n1,2,1,0,0,0,0,0,0\n").expect_err("both").to_string();
        assert!(e.contains(":2:") && e.contains("not both"), "{e}");
        let e =
            read("position,plane,tcp,q1,q2,q3,q4,q5,q6\n,,1,0,0,0,0,0,0\n").expect_err("none").to_string();
        assert!(e.contains(":2:") && e.contains("empty"), "{e}");
        let e = read("plane,tcp,q1,q2,q3,q4,q5,q6,normal\n1,1,0,0,0,0,0,0,maybe\n")
            .expect_err("normal")
            .to_string();
        assert!(e.contains("normal") && e.contains("maybe"), "{e}");
    }
}
