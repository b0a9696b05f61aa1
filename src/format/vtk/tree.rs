//! A whole XML document as a tree of elements, built from quick-xml's event stream.
//!
//! Each [`Element`] keeps its tag name, its attributes (values unescaped and normalised as XML
//! 1.0 prescribes), the line of its start tag (1-based, for messages) and its own text: the
//! concatenation of its text and CDATA pieces, borrowed from the document when it is one piece.
//! Entity references in text are kept verbatim (`&name;`): no VTK array text contains any, and a
//! number or base64 parser then reports them. Declarations, comments, processing instructions
//! and DOCTYPEs are skipped.
//!
//! Errors are `(line, message)` pairs (see [`crate::format::IoError::at_line`]). Nesting is limited
//! to [`MAX_DEPTH`] levels, so a hostile file cannot exhaust the stack when the tree is dropped.

use quick_xml::encoding::EncodingError;
use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};
use std::borrow::Cow;

/// Deepest nesting accepted; VTK files use six levels.
const MAX_DEPTH: usize = 64;

/// `(line, message)`, line 0 for the whole document.
pub(super) type LineError = (usize, String);

/// One XML element with its attributes, own text and child elements.
#[derive(Debug)]
pub(super) struct Element<'a> {
    pub name: String,
    /// Line of the start tag, 1-based.
    pub line: usize,
    attributes: Vec<(String, String)>,
    pub text: Cow<'a, str>,
    pub children: Vec<Element<'a>>,
}

impl<'a> Element<'a> {
    /// The value of attribute `name`, if present.
    pub fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes
            .iter()
            .find(|(key, _)| key == name)
            .map(|(_, value)| value.as_str())
    }

    /// The children named `name`, in document order.
    pub fn children_named<'s>(
        &'s self,
        name: &'s str,
    ) -> impl Iterator<Item = &'s Element<'a>> + 's {
        self.children.iter().filter(move |child| child.name == name)
    }

    /// The first child named `name`.
    pub fn child(&self, name: &str) -> Option<&Element<'a>> {
        self.children.iter().find(|child| child.name == name)
    }

    /// The first child named `name`, or an error at this element's line.
    pub fn required_child(&self, name: &str) -> Result<&Element<'a>, LineError> {
        self.child(name).ok_or_else(|| {
            (
                self.line,
                format!("<{}> has no <{name}> element", self.name),
            )
        })
    }

    /// An error about this element, at its line.
    pub fn error(&self, message: impl Into<String>) -> LineError {
        (self.line, message.into())
    }

    fn append_text(&mut self, piece: Cow<'a, str>) {
        if self.text.is_empty() {
            self.text = piece;
        } else {
            self.text.to_mut().push_str(&piece);
        }
    }
}

/// Parses `text` as an XML document and returns its root element.
pub(super) fn parse_document(text: &str) -> Result<Element<'_>, LineError> {
    let mut reader = Reader::from_str(text);
    let mut lines = LineCounter::new(text);
    // The open elements, innermost last; the root is finished when it is popped.
    let mut open: Vec<Element> = Vec::new();
    loop {
        let start = reader.buffer_position();
        let event = reader.read_event().map_err(|e| {
            let line = lines.line_at(reader.error_position());
            // The parser quotes the file, which may hold line breaks: one line for messages.
            (
                line,
                format!("not well-formed XML: {}", e.to_string().escape_debug()),
            )
        })?;
        let line = lines.line_at(start);
        match event {
            Event::Start(tag) => {
                if open.len() == MAX_DEPTH {
                    return Err((
                        line,
                        format!("elements nested deeper than {MAX_DEPTH} levels"),
                    ));
                }
                open.push(element(&tag, line)?);
            }
            Event::Empty(tag) => {
                let empty = element(&tag, line)?;
                match open.last_mut() {
                    Some(parent) => parent.children.push(empty),
                    None => return Ok(empty),
                }
            }
            Event::End(_) => {
                // quick-xml has checked that the end tag matches the open one.
                let finished = open.pop().ok_or((line, "unmatched end tag".to_string()))?;
                match open.last_mut() {
                    Some(parent) => parent.children.push(finished),
                    None => return Ok(finished),
                }
            }
            Event::Text(piece) => append(&mut open, piece.decode(), line)?,
            Event::CData(piece) => append(&mut open, piece.decode(), line)?,
            Event::GeneralRef(reference) => {
                let verbatim = reference.decode().map(|name| format!("&{name};").into());
                append(&mut open, verbatim, line)?;
            }
            Event::Eof => {
                return Err(match open.last() {
                    Some(inner) => (
                        lines.line_at(reader.buffer_position()),
                        format!(
                            "the file ends inside <{}> (opened at line {})",
                            inner.name, inner.line
                        ),
                    ),
                    None => (0, "no XML element in the file".to_string()),
                });
            }
            Event::Decl(_) | Event::PI(_) | Event::Comment(_) | Event::DocType(_) => {}
        }
    }
}

/// A new element from a start (or empty-element) tag.
fn element<'a>(tag: &BytesStart, line: usize) -> Result<Element<'a>, LineError> {
    let fail = |message: String| (line, message);
    let name = String::from_utf8_lossy(tag.name().as_ref()).into_owned();
    let mut attributes = Vec::new();
    for attribute in tag.attributes() {
        let attribute = attribute.map_err(|e| fail(format!("<{name}>: bad attribute: {e}")))?;
        let key = String::from_utf8_lossy(attribute.key.as_ref()).into_owned();
        let value = attribute
            .normalized_value(XmlVersion::Implicit1_0)
            .map_err(|e| fail(format!("<{name}>: attribute {key}: {e}")))?;
        attributes.push((key, value.into_owned()));
    }
    Ok(Element {
        name,
        line,
        attributes,
        text: Cow::Borrowed(""),
        children: Vec::new(),
    })
}

/// Adds a piece of text to the innermost open element; text outside the root must be
/// whitespace.
fn append<'a>(
    open: &mut [Element<'a>],
    piece: Result<Cow<'a, str>, EncodingError>,
    line: usize,
) -> Result<(), LineError> {
    let piece = piece.map_err(|e| (line, e.to_string()))?;
    match open.last_mut() {
        Some(parent) => parent.append_text(piece),
        None if piece.trim().is_empty() => {}
        None => {
            let start: String = piece.trim().chars().take(20).collect();
            return Err((line, format!("text outside the root element: '{start}'")));
        }
    }
    Ok(())
}

/// Line numbers of byte positions, counted forward as the reader advances.
struct LineCounter<'a> {
    text: &'a [u8],
    position: usize,
    line: usize,
}

impl<'a> LineCounter<'a> {
    fn new(text: &'a str) -> Self {
        Self {
            text: text.as_bytes(),
            position: 0,
            line: 1,
        }
    }

    /// The 1-based line of byte `position`; positions must not decrease between calls.
    fn line_at(&mut self, position: u64) -> usize {
        let target = usize::try_from(position)
            .unwrap_or(usize::MAX)
            .clamp(self.position, self.text.len());
        let newlines = self.text[self.position..target]
            .iter()
            .filter(|&&byte| byte == b'\n')
            .count();
        self.line += newlines;
        self.position = target;
        self.line
    }
}
