//! The report folder being written (`ReportWriter`): the README's text, its tables and figures,
//! published whole at the end; a leaf below the sections, which all write through it.

use std::path::{Path, PathBuf};

use polars::prelude::*;

use store::atomic_file::write_atomic;
use store::tables;

use crate::chart::{Figure, render};
use crate::error::ReportError;
use crate::{markdown, publish};

/// What a report wrote.
#[derive(Debug)]
pub struct ReportSummary {
    pub folder: PathBuf,
    pub tables: usize,
    pub figures: usize,
    /// The bytes of the table store it carries in `store/`.
    pub store_bytes: u64,
}

/// The report folder being written: the README's text, and its tables and figures.
pub(crate) struct ReportWriter {
    publication: publish::Publication,
    readme: String,
    tables: usize,
    figures: usize,
}

impl ReportWriter {
    pub(crate) fn new(reports_root: &Path, name: &str) -> Result<Self, ReportError> {
        let publication = publish::Publication::start(reports_root, name)?;
        for sub in ["tables", "figures"] {
            let path = publication.fresh.join(sub);
            std::fs::create_dir_all(&path).map_err(|source| ReportError::Io { path, source })?;
        }
        Ok(Self {
            publication,
            readme: String::new(),
            tables: 0,
            figures: 0,
        })
    }

    /// Where the report is written until it is whole.
    pub(crate) fn folder(&self) -> &Path {
        &self.publication.fresh
    }

    pub(crate) fn heading(&mut self, level: usize, text: &str) {
        self.readme += &format!("{} {text}\n\n", "#".repeat(level));
    }

    pub(crate) fn paragraph(&mut self, text: &str) {
        self.readme += text;
        self.readme += "\n\n";
    }

    /// Writes `tables/NAME.parquet` and `tables/NAME.md`, and shows the table in the README.
    pub(crate) fn table(&mut self, name: &str, frame: &DataFrame) -> Result<(), ReportError> {
        let markdown = markdown::table(frame)?;
        self.write(
            &format!("tables/{name}.parquet"),
            &tables::parquet_bytes(frame)?,
        )?;
        self.write(&format!("tables/{name}.md"), markdown.as_bytes())?;
        self.tables += 1;
        self.readme += &markdown;
        self.readme += &format!("\n([Parquet](tables/{name}.parquet))\n\n");
        Ok(())
    }

    /// Writes a table too long to read (per step or per cell) as Parquet only, and links it.
    pub(crate) fn linked_table(
        &mut self,
        name: &str,
        frame: &DataFrame,
        what: &str,
    ) -> Result<(), ReportError> {
        self.write(
            &format!("tables/{name}.parquet"),
            &tables::parquet_bytes(frame)?,
        )?;
        self.tables += 1;
        self.readme += &format!(
            "{what}: [Parquet](tables/{name}.parquet) ({} rows).\n\n",
            frame.height()
        );
        Ok(())
    }

    /// Writes `figures/NAME.png`, and `figures/NAME.svg` unless it is large, and shows the PNG
    /// in the README.
    pub(crate) fn figure(
        &mut self,
        name: &str,
        figure: &impl Figure,
        caption: &str,
    ) -> Result<(), ReportError> {
        let rendered = render(figure)?;
        self.write(&format!("figures/{name}.png"), &rendered.png)?;
        let svg = if rendered.svg.len() <= MAX_SVG_BYTES {
            self.write(&format!("figures/{name}.svg"), rendered.svg.as_bytes())?;
            format!("[SVG](figures/{name}.svg)")
        } else {
            format!("SVG of {} KB left out", rendered.svg.len() / 1000)
        };
        self.figures += 1;
        self.readme += &format!("![{caption}](figures/{name}.png)\n\n*{caption}* ({svg})\n\n");
        Ok(())
    }

    pub(crate) fn write(&mut self, relative: &str, bytes: &[u8]) -> Result<(), ReportError> {
        let path = self.folder().join(relative);
        write_atomic(&path, bytes).map_err(|source| ReportError::Io { path, source })
    }

    /// Writes the README and puts the whole folder in the last report's place: the folder
    /// then holds exactly what the README shows, and nothing of an earlier report.
    pub(crate) fn finish(mut self, store_bytes: u64) -> Result<ReportSummary, ReportError> {
        let readme = std::mem::take(&mut self.readme);
        self.write("README.md", readme.as_bytes())?;
        Ok(ReportSummary {
            folder: self.publication.swap_in()?,
            tables: self.tables,
            figures: self.figures,
            store_bytes,
        })
    }
}

/// The largest SVG a report keeps. Maps and trajectories draw a shape per cell or step, and
/// their SVGs run to hundreds of KB; their PNGs stand, so that a report stays small enough to
/// commit.
const MAX_SVG_BYTES: usize = 100_000;

/// A name safe in file names: letters, digits and `-`, everything else `_`.
pub(crate) fn file_stem(parts: &[&str]) -> String {
    parts
        .join("_")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}
