//! [`SceneError`]: every problem with a scene file, located as
//! `FILE:LINE:COL: message` (1-based line and column; the column counts
//! characters, not bytes).

use std::fmt;
use std::path::{Path, PathBuf};

/// An error while reading, parsing or validating a scene.
///
/// Displays as `FILE:LINE:COL: message`, or `FILE: message` when the error
/// has no position (an I/O error, for instance). One pointer wide, so that
/// the readers' `Result`s stay small on their hot paths.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{}: {}", Location(&self.0.file, self.0.line, self.0.column), self.0.message)]
pub struct SceneError(Box<Inner>);

#[derive(Clone, Debug, PartialEq, Eq)]
struct Inner {
    file: PathBuf,
    line: Option<usize>,
    column: Option<usize>,
    message: String,
}

struct Location<'a>(&'a Path, Option<usize>, Option<usize>);

impl fmt::Display for Location<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0.display())?;
        if let Some(line) = self.1 {
            write!(f, ":{line}")?;
            if let Some(col) = self.2 {
                write!(f, ":{col}")?;
            }
        }
        Ok(())
    }
}

impl SceneError {
    /// The file could not be read. The message gives the reason; the path
    /// is the location (`FILE: cannot read: REASON`), named once.
    pub fn io(path: &Path, err: &std::io::Error) -> Self {
        Self::in_file(path, format!("cannot read: {err}"))
    }

    /// An error at a 1-based `line` and `column` of `path`.
    pub fn at(path: &Path, line: usize, column: usize, message: impl Into<String>) -> Self {
        SceneError(Box::new(Inner {
            file: path.to_path_buf(),
            line: Some(line),
            column: Some(column),
            message: message.into(),
        }))
    }

    /// An error at byte offset `byte_offset` of `text`, the contents of
    /// `path`. Offsets past the end point just after the last character; an
    /// offset inside a UTF-8 sequence is moved back to its start.
    pub fn at_offset(
        path: &Path,
        text: &str,
        byte_offset: usize,
        message: impl Into<String>,
    ) -> Self {
        let (line, column) = line_col(text, byte_offset);
        Self::at(path, line, column, message)
    }

    /// An error about the whole file, with no position.
    pub fn in_file(path: &Path, message: impl Into<String>) -> Self {
        SceneError(Box::new(Inner {
            file: path.to_path_buf(),
            line: None,
            column: None,
            message: message.into(),
        }))
    }

    /// The scene file the error is in.
    pub fn file(&self) -> &Path {
        &self.0.file
    }

    /// 1-based line, if known.
    pub fn line(&self) -> Option<usize> {
        self.0.line
    }

    /// 1-based column in characters, if known.
    pub fn column(&self) -> Option<usize> {
        self.0.column
    }

    /// The message without the location.
    pub fn message(&self) -> &str {
        &self.0.message
    }
}

/// 1-based (line, column) of byte offset `offset` in `text`; the column
/// counts characters.
pub(crate) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let column = before[line_start..].chars().count() + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_with_position() {
        let e = SceneError::at(
            Path::new("scenes/bad.toml"),
            7,
            12,
            "radius must be > 0, got 0",
        );
        assert_eq!(
            e.to_string(),
            "scenes/bad.toml:7:12: radius must be > 0, got 0"
        );
        assert_eq!(e.line(), Some(7));
        assert_eq!(e.column(), Some(12));
        assert_eq!(e.message(), "radius must be > 0, got 0");
        assert_eq!(e.file(), Path::new("scenes/bad.toml"));
    }

    #[test]
    fn display_without_position() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "gone");
        let e = SceneError::io(Path::new("a/b.toml"), &io);
        assert_eq!(e.to_string(), "a/b.toml: cannot read: gone");
        assert_eq!(e.line(), None);
        assert_eq!(e.column(), None);
    }

    #[test]
    fn offsets_to_line_and_column() {
        let text = "ab\ncdé\nfg";
        assert_eq!(line_col(text, 0), (1, 1));
        assert_eq!(line_col(text, 2), (1, 3));
        assert_eq!(line_col(text, 3), (2, 1));
        // 'é' is two bytes: 'f' is at byte 8, column 1 of line 3.
        assert_eq!(line_col(text, 8), (3, 1));
        assert_eq!(line_col(text, 7), (2, 4));
        // inside 'é' → moved back to its start
        assert_eq!(line_col(text, 6), (2, 3));
        assert_eq!(line_col(text, 1000), (3, 3));
        let e = SceneError::at_offset(Path::new("x"), text, 4, "m");
        assert_eq!(e.to_string(), "x:2:2: m");
    }
}
