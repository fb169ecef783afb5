//! VRML tokens: numbers, names, strings, brackets, with line numbers for errors.

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Kind {
    Open,
    Close,
    LBracket,
    RBracket,
    Word,
    Str,
    Eof,
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Tok<'a> {
    pub(super) kind: Kind,
    pub(super) text: &'a [u8],
    pub(super) line: usize,
}

pub(super) struct Lexer<'a> {
    pub(super) s: &'a [u8],
    pub(super) pos: usize,
    pub(super) line: usize,
    pub(super) peeked: Option<Tok<'a>>,
}

impl<'a> Lexer<'a> {
    pub(super) fn new(s: &'a [u8]) -> Self {
        Lexer {
            s,
            pos: 0,
            line: 1,
            peeked: None,
        }
    }

    pub(super) fn peek(&mut self) -> std::result::Result<Tok<'a>, (usize, &'static str)> {
        if let Some(t) = self.peeked {
            return Ok(t);
        }
        let t = self.lex()?;
        self.peeked = Some(t);
        Ok(t)
    }

    pub(super) fn next(&mut self) -> std::result::Result<Tok<'a>, (usize, &'static str)> {
        match self.peeked.take() {
            Some(t) => Ok(t),
            None => self.lex(),
        }
    }

    /// Whitespace includes commas (VRML treats them as separators) and `#` comments.
    pub(super) fn lex(&mut self) -> std::result::Result<Tok<'a>, (usize, &'static str)> {
        let s = self.s;
        while let Some(&c) = s.get(self.pos) {
            match c {
                b'\n' => {
                    self.line += 1;
                    self.pos += 1;
                }
                b' ' | b'\t' | b'\r' | b',' | 0x0b | 0x0c => self.pos += 1,
                b'#' => {
                    while let Some(&c) = s.get(self.pos) {
                        if c == b'\n' {
                            break;
                        }
                        self.pos += 1;
                    }
                }
                _ => break,
            }
        }
        let start = self.pos;
        let line = self.line;
        let Some(&c) = s.get(start) else {
            return Ok(Tok {
                kind: Kind::Eof,
                text: &[],
                line,
            });
        };
        let single = |kind| Tok {
            kind,
            text: &s[start..start + 1],
            line,
        };
        let tok = match c {
            b'{' => single(Kind::Open),
            b'}' => single(Kind::Close),
            b'[' => single(Kind::LBracket),
            b']' => single(Kind::RBracket),
            b'"' => {
                let mut i = start + 1;
                loop {
                    match s.get(i) {
                        None => return Err((line, "unterminated string")),
                        Some(b'\\') => i += 2,
                        Some(b'"') => break,
                        Some(b'\n') => {
                            self.line += 1;
                            i += 1;
                        }
                        Some(_) => i += 1,
                    }
                }
                self.pos = i + 1;
                return Ok(Tok {
                    kind: Kind::Str,
                    text: s.get(start + 1..i).unwrap_or(&[]),
                    line,
                });
            }
            _ => {
                let mut i = start;
                while let Some(&c) = s.get(i) {
                    if matches!(
                        c,
                        b' ' | b'\t'
                            | b'\r'
                            | b'\n'
                            | b','
                            | b'{'
                            | b'}'
                            | b'['
                            | b']'
                            | b'"'
                            | b'#'
                            | 0x0b
                            | 0x0c
                    ) {
                        break;
                    }
                    i += 1;
                }
                self.pos = i;
                return Ok(Tok {
                    kind: Kind::Word,
                    text: &s[start..i],
                    line,
                });
            }
        };
        self.pos = start + 1;
        Ok(tok)
    }
}

/// A token for an error message: lossy text, cut to 40 characters.
pub(super) fn show(text: &[u8]) -> String {
    let s = String::from_utf8_lossy(text);
    let mut out: String = s.chars().take(40).collect();
    if s.chars().count() > 40 {
        out.push('…');
    }
    out.replace(|c: char| c.is_control(), "?")
}

pub(super) fn parse_f64(text: &[u8]) -> Option<f64> {
    std::str::from_utf8(text).ok()?.parse::<f64>().ok()
}

pub(super) fn parse_i64(text: &[u8]) -> Option<i64> {
    let s = std::str::from_utf8(text).ok()?;
    if let Some(hex) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        return i64::from_str_radix(hex, 16).ok();
    }
    s.parse::<i64>().ok()
}
