//! CSV output files with their sidecar (`gonio_process::file`): the CSV that
//! `pandas.read_csv(path)` reads with no arguments, and `PATH.json` beside it with
//! what its header cannot say (a table's grid, isotropy). Both are [`Target`]s:
//! checked before any work is done, each written whole or not at all.

use std::path::Path;

use gonio_process::file::{self, Meta};
use gonio_process::{Samples, Table};

use crate::error::{CliError, CliResult};
use crate::output::Target;

/// A CSV output and its sidecar.
#[derive(Clone, Debug)]
pub struct CsvTarget {
    csv: Target,
    sidecar: Target,
}

impl CsvTarget {
    /// Checks both files as [`Target::new`] does (an existing sidecar, too, needs
    /// `--force`).
    pub fn new(path: &Path, force: bool) -> CliResult<CsvTarget> {
        Ok(CsvTarget {
            csv: Target::new(path, force)?,
            sidecar: Target::new(&file::sidecar_path(path), force)?,
        })
    }

    /// The CSV file.
    pub fn path(&self) -> &Path {
        self.csv.path()
    }

    /// Writes the CSV, then its sidecar. A sidecar already there is removed first:
    /// a failure between the two writes then leaves a CSV without a sidecar, which
    /// still reads (its grid recognised from the rows), never one beside the sidecar
    /// of another file.
    pub fn write(&self, csv: &[u8], meta: &Meta) -> CliResult<()> {
        let side = self.sidecar.path();
        match std::fs::remove_file(side) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(CliError::Runtime(format!(
                    "{}: cannot replace the sidecar: {e}",
                    side.display()
                )));
            }
            _ => {}
        }
        self.csv.write(csv)?;
        self.sidecar.write(meta.to_json().as_bytes())
    }

    /// Writes a table ([`file::write_table`]) and its sidecar; the bytes of the CSV.
    pub fn write_table(&self, t: &Table) -> CliResult<usize> {
        let text = file::write_table(t);
        self.write(text.as_bytes(), &Meta::for_table(t))?;
        Ok(text.len())
    }

    /// Writes a table made from an input ([`gonio_dataset::Dataset::tabulate`]), its
    /// sidecar saying what was assumed: the symmetry, the nodes interpolated.
    pub fn write_tabulated(&self, t: &Table, how: &gonio_dataset::Tabulated) -> CliResult<usize> {
        let text = file::write_table(t);
        self.write(text.as_bytes(), &tabulated_meta(t, how))?;
        Ok(text.len())
    }

    /// Writes samples ([`file::write_samples`]) and their sidecar, with the
    /// reduction's covariance when given; the bytes of the CSV.
    pub fn write_samples(
        &self,
        s: &Samples,
        covariance: Option<&gonio_process::covariance::Covariance>,
    ) -> CliResult<usize> {
        let text = file::write_samples(s);
        let mut meta = Meta::for_samples(s);
        meta.covariance = covariance.cloned();
        self.write(text.as_bytes(), &meta)?;
        Ok(text.len())
    }
}

/// The sidecar of a table made from an input ([`gonio_dataset::Dataset::tabulate`]):
/// its grid, and what was assumed of measured data — the symmetry, the nodes
/// interpolated.
pub(crate) fn tabulated_meta(t: &Table, how: &gonio_dataset::Tabulated) -> Meta {
    let mut meta = Meta::for_table(t);
    if how.measured.is_some() {
        meta.symmetry = Some(how.symmetry.name().into());
        meta.interpolated = Some(
            how.fill
                .as_ref()
                .map(|f| f.interpolated.clone())
                .unwrap_or_default(),
        );
    }
    meta
}
