//! Result reporting shared by the commands: JSON files with a `rows` array and markdown tables.

use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;

/// Writes `{"command": ..., "rows": [...], ...extra}` as pretty JSON.
pub fn write_json<T: Serialize>(path: &Path, command: &str, rows: &[T], extra: serde_json::Value) -> Result<()> {
    let mut obj = serde_json::json!({ "command": command, "rows": rows });
    if let (Some(o), serde_json::Value::Object(e)) = (obj.as_object_mut(), extra) {
        o.extend(e);
    }
    if let Some(dir) = path.parent() {
        if !dir.as_os_str().is_empty() {
            std::fs::create_dir_all(dir).with_context(|| format!("{}: cannot create folder", dir.display()))?;
        }
    }
    let text = serde_json::to_string_pretty(&obj)?;
    std::fs::write(path, text).with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(())
}

/// A markdown table printer.
pub struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// A table with the given column names.
    pub fn new(header: &[&str]) -> Self {
        Table { header: header.iter().map(|s| s.to_string()).collect(), rows: Vec::new() }
    }
    /// Appends a row.
    pub fn row(&mut self, cells: Vec<String>) {
        self.rows.push(cells);
    }
    /// Renders as a markdown table with aligned columns.
    pub fn render(&self) -> String {
        let n = self.header.len();
        let mut w: Vec<usize> = self.header.iter().map(|h| h.len()).collect();
        for r in &self.rows {
            for (i, c) in r.iter().enumerate().take(n) {
                w[i] = w[i].max(c.len());
            }
        }
        let line = |cells: &[String]| {
            let mut s = String::from("|");
            for (i, width) in w.iter().enumerate() {
                let c = cells.get(i).map(String::as_str).unwrap_or("");
                s.push_str(&format!(" {c:<width$} |"));
            }
            s
        };
        let mut out = line(&self.header);
        out.push('\n');
        out.push('|');
        for wi in &w {
            out.push_str(&format!("{}|", "-".repeat(wi + 2)));
        }
        for r in &self.rows {
            out.push('\n');
            out.push_str(&line(r));
        }
        out
    }
}

/// Formats a float with `d` decimals, `inf` for infinities.
pub fn fmt(x: f64, d: usize) -> String {
    if x.is_infinite() {
        "inf".into()
    } else {
        format!("{:.*}", d, x)
    }
}

/// Serializes an `f64` as a JSON number, or as the string `"inf"` / `"-inf"` / `"nan"` when it is
/// not finite (JSON has no infinity; PSNR of identical images is `inf`).
pub fn ser_f64<S: serde::Serializer>(x: &f64, s: S) -> std::result::Result<S::Ok, S::Error> {
    if x.is_finite() {
        s.serialize_f64(*x)
    } else if x.is_nan() {
        s.serialize_str("nan")
    } else if *x > 0.0 {
        s.serialize_str("inf")
    } else {
        s.serialize_str("-inf")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_layout() {
        let mut t = Table::new(&["a", "bb"]);
        t.row(vec!["xxx".into(), "y".into()]);
        assert_eq!(t.render(), "| a   | bb |\n|-----|----|\n| xxx | y  |");
    }
}
