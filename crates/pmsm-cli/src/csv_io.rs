//! CSV input and output with named, unit-suffixed columns.
//!
//! Reading checks what a user gets wrong most: a missing column, a short row, a cell that is
//! not a finite number, a time column that does not increase. Every error is one line that
//! names the file, the data row (1-based, the header is not counted), the file line and the
//! column. Columns may come in any order; columns that are not asked for are ignored.

use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};

/// Numeric columns read from a CSV file, column-major.
#[derive(Debug)]
pub struct Table {
    /// The file the table came from (for messages).
    pub path: PathBuf,
    names: Vec<String>,
    columns: Vec<Vec<f64>>,
}

impl Table {
    /// The values of `name`, if the column was requested and present.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.names
            .iter()
            .position(|n| n == name)
            .and_then(|i| self.columns.get(i))
            .map(Vec::as_slice)
    }

    /// The values of a required column (always present after [`read`]).
    pub fn required(&self, name: &str) -> Result<&[f64]> {
        self.column(name)
            .with_context(|| format!("{}: missing column `{name}`", self.path.display()))
    }

    /// Number of data rows.
    pub fn rows(&self) -> usize {
        self.columns.first().map_or(0, Vec::len)
    }
}

/// Reads the `required` and (when present) `optional` columns of `path` as finite numbers.
pub fn read(path: &Path, required: &[&str], optional: &[&str]) -> Result<Table> {
    let file =
        std::fs::File::open(path).with_context(|| format!("{}: cannot open", path.display()))?;
    read_from(file, path, required, optional)
}

/// As [`read`], from any reader; `path` is used in messages only.
pub fn read_from(
    input: impl std::io::Read,
    path: &Path,
    required: &[&str],
    optional: &[&str],
) -> Result<Table> {
    let shown = path.display();
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(input);
    let header = header_row(&mut reader, path, required)?;
    let wanted = select_columns(&header, path, required, optional)?;
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); wanted.len()];
    for (row, record) in reader.records().enumerate() {
        let row = row + 1;
        let record = record.with_context(|| format!("{shown}: row {row}: unreadable"))?;
        let line = record
            .position()
            .map_or(row as u64 + 1, csv::Position::line);
        if record.len() != header.len() {
            bail!(
                "{shown}: row {row} (line {line}) has {} fields, the header has {}",
                record.len(),
                header.len()
            );
        }
        for ((name, index), column) in wanted.iter().zip(columns.iter_mut()) {
            let cell = record.get(*index).unwrap_or("");
            let value = finite_number(cell).map_err(|what| {
                anyhow::anyhow!(
                    "{shown}: row {row} (line {line}), column `{name}`: `{cell}` is not {what}"
                )
            })?;
            column.push(value);
        }
    }
    let table = Table {
        path: path.to_owned(),
        names: wanted.into_iter().map(|w| w.0).collect(),
        columns,
    };
    if table.rows() == 0 {
        bail!("{shown}: no data rows after the header");
    }
    Ok(table)
}

/// The column names; an empty file is an error that lists the `required` columns.
fn header_row<R: std::io::Read>(
    reader: &mut csv::Reader<R>,
    path: &Path,
    required: &[&str],
) -> Result<Vec<String>> {
    let shown = path.display();
    let header: Vec<String> = reader
        .headers()
        .with_context(|| format!("{shown}: cannot read the header row"))?
        .iter()
        .map(str::to_owned)
        .collect();
    if header.iter().all(String::is_empty) {
        bail!(
            "{shown}: empty file (expected a header row with {})",
            required.join(", ")
        );
    }
    Ok(header)
}

/// Each wanted column's name and position in `header`: every `required` one, then the
/// `optional` ones present.
fn select_columns(
    header: &[String],
    path: &Path,
    required: &[&str],
    optional: &[&str],
) -> Result<Vec<(String, usize)>> {
    let mut wanted: Vec<(String, usize)> = Vec::new();
    for name in required {
        match header.iter().position(|h| h == name) {
            Some(i) => wanted.push(((*name).to_owned(), i)),
            None => bail!(
                "{}: missing column `{name}` (the header has: {})",
                path.display(),
                header.join(", ")
            ),
        }
    }
    for name in optional {
        if let Some(i) = header.iter().position(|h| h == name) {
            wanted.push(((*name).to_owned(), i));
        }
    }
    Ok(wanted)
}

/// A cell as a finite number, or what it fails to be.
fn finite_number(cell: &str) -> Result<f64, &'static str> {
    let value: f64 = cell.parse().map_err(|_| "a number")?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err("a finite number")
    }
}

/// Checks that a time column is strictly increasing; returns its rows.
pub fn check_time(table: &Table, name: &str) -> Result<usize> {
    let t = table.required(name)?;
    for (k, pair) in t.windows(2).enumerate() {
        if let [a, b] = pair
            && b <= a
        {
            bail!(
                "{}: row {}, column `{name}`: time must increase ({b} after {a})",
                table.path.display(),
                k + 2
            );
        }
    }
    Ok(t.len())
}

/// Writes rows of numbers under a header; refuses to write a non-finite value.
pub struct Writer {
    path: PathBuf,
    inner: csv::Writer<std::fs::File>,
    width: usize,
    rows: usize,
}

impl Writer {
    /// Creates `path` and writes the header.
    pub fn create(path: &Path, header: &[&str]) -> Result<Self> {
        let mut inner = csv::Writer::from_path(path)
            .with_context(|| format!("{}: cannot create", path.display()))?;
        inner
            .write_record(header)
            .with_context(|| format!("{}: cannot write", path.display()))?;
        Ok(Self {
            path: path.to_owned(),
            inner,
            width: header.len(),
            rows: 0,
        })
    }

    /// Writes one row; every value must be finite.
    pub fn row(&mut self, values: &[f64]) -> Result<()> {
        if values.len() != self.width {
            bail!(
                "{}: internal error: row of {} values for {} columns",
                self.path.display(),
                values.len(),
                self.width
            );
        }
        if let Some(bad) = values.iter().position(|v| !v.is_finite()) {
            bail!(
                "{}: row {}: refusing to write a non-finite value in column {}",
                self.path.display(),
                self.rows + 1,
                bad + 1
            );
        }
        self.inner
            .write_record(values.iter().map(|v| v.to_string()))
            .with_context(|| format!("{}: cannot write", self.path.display()))?;
        self.rows += 1;
        Ok(())
    }

    /// Flushes the file.
    pub fn finish(mut self) -> Result<usize> {
        self.inner
            .flush()
            .with_context(|| format!("{}: cannot write", self.path.display()))?;
        Ok(self.rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Table> {
        read_from(
            text.as_bytes(),
            Path::new("in.csv"),
            &["t_s", "v_alpha_v"],
            &["load_nm"],
        )
    }

    fn message(text: &str) -> String {
        format!("{:#}", parse(text).unwrap_err())
    }

    #[test]
    fn columns_in_any_order_and_extras_ignored() {
        let t = parse("note,v_alpha_v,t_s\nx,1.5,0\ny,2.5,0.1\n").unwrap();
        assert_eq!(t.column("v_alpha_v"), Some(&[1.5, 2.5][..]));
        assert_eq!(t.column("t_s"), Some(&[0.0, 0.1][..]));
        assert_eq!(t.column("load_nm"), None);
        assert_eq!(t.rows(), 2);
    }

    #[test]
    fn errors_name_file_row_and_column() {
        assert_eq!(
            message("t_s,v_beta_v\n0,1\n"),
            "in.csv: missing column `v_alpha_v` (the header has: t_s, v_beta_v)"
        );
        assert_eq!(
            message("t_s,v_alpha_v\n0,1\n0.1,abc\n"),
            "in.csv: row 2 (line 3), column `v_alpha_v`: `abc` is not a number"
        );
        assert_eq!(
            message("t_s,v_alpha_v\n0,NaN\n"),
            "in.csv: row 1 (line 2), column `v_alpha_v`: `NaN` is not a finite number"
        );
        assert_eq!(
            message("t_s,v_alpha_v\n0,1\n0.1\n"),
            "in.csv: row 2 (line 3) has 1 fields, the header has 2"
        );
        assert_eq!(
            message("t_s,v_alpha_v\n"),
            "in.csv: no data rows after the header"
        );
        assert!(message("").starts_with("in.csv: empty file"));
    }

    #[test]
    fn time_must_increase() {
        let t = parse("t_s,v_alpha_v\n0,1\n0.1,1\n0.1,1\n").unwrap();
        let e = format!("{:#}", check_time(&t, "t_s").unwrap_err());
        assert_eq!(
            e,
            "in.csv: row 3, column `t_s`: time must increase (0.1 after 0.1)"
        );
    }
}
