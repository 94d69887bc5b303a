//! The files of a run folder as they are written, in order: the list the summary's "Files"
//! section shows (every writer of the run goes through [`Files`] or notes its file here).

use std::path::{Path, PathBuf};

use serde::Serialize;
use vatcal_core::{CellFile, JointKind, Measurement};
use vatcal_report::save_svg;

use crate::PipelineError;
use crate::folders::PLAN_FILES;

/// Writes the files of the report folder and remembers their names.
pub(crate) struct Files {
    out: PathBuf,
    written: Vec<PathBuf>,
    /// the joints of the cell's chain (the measurement files' `q1..qN`, `dir{j}`)
    kinds: Vec<JointKind>,
}

impl Files {
    /// The writer of the run folder `out` of a chain with joints `kinds`.
    pub fn new(out: &Path, kinds: &[JointKind]) -> Self {
        Self { out: out.to_path_buf(), written: Vec::new(), kinds: kinds.to_vec() }
    }

    /// The files written or noted so far, in order.
    pub fn written(&self) -> &[PathBuf] {
        &self.written
    }

    /// Remembers a file written by someone else.
    pub fn note(&mut self, name: impl Into<PathBuf>) {
        self.written.push(name.into());
    }

    /// Remembers the files of the plan folder `dir` (`plan/…`).
    pub fn note_plan(&mut self, dir: &str) {
        for name in PLAN_FILES {
            self.note(Path::new(dir).join(name));
        }
    }

    /// Writes a text file.
    pub fn text(&mut self, name: &str, text: &str) -> Result<(), PipelineError> {
        let path = self.out.join(name);
        std::fs::write(&path, text).map_err(|source| PipelineError::Io { path, source })?;
        self.note(name);
        Ok(())
    }

    /// Writes a cell file.
    pub fn cell(&mut self, name: &str, cell: &CellFile) -> Result<(), PipelineError> {
        cell.save(self.out.join(name))?;
        self.note(name);
        Ok(())
    }

    /// Writes a measurements CSV.
    pub fn measurements(&mut self, name: &str, m: &[Measurement]) -> Result<(), PipelineError> {
        vatcal_io::write_measurements_for(self.out.join(name), m, &self.kinds)?;
        self.note(name);
        Ok(())
    }

    /// Writes a JSON file (pretty).
    pub fn json(&mut self, name: &str, value: &impl Serialize) -> Result<(), PipelineError> {
        let text = serde_json::to_string_pretty(value)?;
        self.text(name, &text)
    }

    /// Writes an SVG file.
    pub fn svg(&mut self, name: &str, svg: &str) -> Result<(), PipelineError> {
        save_svg(self.out.join(name), svg)?;
        self.note(name);
        Ok(())
    }
}
