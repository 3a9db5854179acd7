//! The plain-text tables of `hdrcodec bench` and its report: every column as wide as its widest
//! cell (header included), so that a long label (`jxr(jxrlib-enc):lossless`, a cropped image
//! `NAME@c256x256`) widens its column instead of pushing the rest of its line to the right.

/// How a column's cells sit in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Align {
    /// Text: flush left.
    Left,
    /// Figures: flush right.
    Right,
}

/// A table built row by row and laid out once every row is in.
#[derive(Clone, Debug)]
pub struct TextTable {
    aligns: Vec<Align>,
    lines: Vec<Line>,
}

/// One line: its cells, and what follows them.
#[derive(Clone, Debug)]
struct Line {
    cells: Vec<String>,
    after: After,
}

/// What follows a line's cells.
#[derive(Clone, Debug)]
enum After {
    /// Text after the last column (every column laid out, empty ones blank).
    Columns(String),
    /// Text right after the line's own cells, across the columns it does not fill.
    Note(String),
}

/// The gap between two columns.
const GAP: &str = "  ";

impl TextTable {
    /// A table with these columns (header text and alignment); the header is its first line.
    pub fn new(columns: &[(&str, Align)]) -> Self {
        let aligns = columns.iter().map(|c| c.1).collect();
        let header = columns.iter().map(|c| c.0.to_string()).collect();
        TextTable { aligns, lines: vec![Line { cells: header, after: After::Columns(String::new()) }] }
    }

    /// A line with a cell for each column (fewer leave the last columns empty), then `tail`
    /// after the last column (a marker such as `DIFFERS FROM PEER`; empty for none).
    pub fn row(&mut self, cells: Vec<String>, tail: &str) {
        self.lines.push(Line { cells, after: After::Columns(tail.to_string()) });
    }

    /// A line whose first cells sit in their columns and whose `text` follows them, outside
    /// the columns (why a row has no figures).
    pub fn note_row(&mut self, cells: Vec<String>, text: &str) {
        self.lines.push(Line { cells, after: After::Note(text.to_string()) });
    }

    /// The lines, each ending in a newline, without trailing blanks.
    pub fn render(&self) -> String {
        let mut widths = vec![0; self.aligns.len()];
        for l in &self.lines {
            for (w, c) in widths.iter_mut().zip(&l.cells) {
                *w = (*w).max(c.chars().count());
            }
        }
        let mut s = String::new();
        for l in &self.lines {
            let mut line = String::new();
            // A note line lays out only the cells it has; a full line every column.
            let shown = if matches!(l.after, After::Note(_)) { l.cells.len() } else { self.aligns.len() };
            for (k, (&align, &w)) in self.aligns.iter().zip(&widths).enumerate().take(shown) {
                let cell = l.cells.get(k).map_or("", String::as_str);
                if k > 0 {
                    line.push_str(GAP);
                }
                match align {
                    Align::Left => line.push_str(&format!("{cell:<w$}")),
                    Align::Right => line.push_str(&format!("{cell:>w$}")),
                }
            }
            match &l.after {
                After::Note(text) => {
                    line.push_str(GAP);
                    line.push_str(text);
                }
                After::Columns(tail) => line.push_str(tail),
            }
            s.push_str(line.trim_end());
            s.push('\n');
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_are_as_wide_as_their_widest_cell() {
        let mut t = TextTable::new(&[("config", Align::Left), ("bytes", Align::Right), ("image", Align::Left)]);
        t.row(vec!["jxr(jxrlib-enc):lossless".into(), "12".into(), "a.exr".into()], "");
        t.row(vec!["rgbe".into(), "1234567".into(), "StillLife.exr@c256x256".into()], "  DIFFERS");
        t.note_row(vec!["bc6h(ispc):fast".into()], "not installed: ispc");
        let text = t.render();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines,
            [
                "config                      bytes  image",
                "jxr(jxrlib-enc):lossless       12  a.exr",
                "rgbe                      1234567  StillLife.exr@c256x256  DIFFERS",
                "bc6h(ispc):fast           not installed: ispc",
            ]
        );
    }

    #[test]
    fn missing_cells_are_blank_and_lines_have_no_trailing_blanks() {
        let mut t = TextTable::new(&[("a", Align::Left), ("b", Align::Right), ("c", Align::Left)]);
        t.row(vec!["xyz".into()], "");
        assert_eq!(t.render(), "a    b  c\nxyz\n");
    }
}
