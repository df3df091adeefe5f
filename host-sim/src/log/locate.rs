//! Which field a byte offset of a JSON line falls in, for lines that do not
//! parse (truncated, a `NaN` literal, a line over the length cap): the error can
//! then name the field, e.g. `part_px[1][0]`, as every other log error does.
//!
//! A small scanner over the text before the offset, not a parser: it tracks the
//! open objects and arrays, the last key of each object and the index within
//! each array. Whatever follows the offset is never looked at, so it works on a
//! prefix of a line that was cut off.

/// One open container.
enum Open {
    /// An object and the key whose value is being read (`None` between members).
    Object(Option<String>),
    /// An array and the index of the element being read.
    Array(usize),
}

/// The key path (`camera.f_px`, `part_px[2][0]`) at byte `end` of `text`, or
/// `None` when `end` is outside any member (e.g. before the first key).
pub fn field_at(text: &[u8], end: usize) -> Option<String> {
    let prefix = text.get(..end.min(text.len()))?;
    let mut stack: Vec<Open> = Vec::new();
    // The string being read, and whether it sits where an object key goes.
    let mut string: Option<(Vec<u8>, bool)> = None;
    let mut escaped = false;
    let mut pending_key: Option<String> = None;
    for &byte in prefix {
        if let Some((content, is_key)) = string.as_mut() {
            // Only keys are kept: a value string may be megabytes long.
            if escaped {
                escaped = false;
            } else if byte == b'\\' {
                escaped = true;
                continue;
            } else if byte == b'"' {
                if let Some((content, true)) = string.take() {
                    pending_key = Some(String::from_utf8_lossy(&content).into_owned());
                }
                continue;
            }
            if *is_key {
                content.push(byte);
            }
            continue;
        }
        match byte {
            b'"' => {
                let is_key = matches!(stack.last(), Some(Open::Object(None)));
                string = Some((Vec::new(), is_key));
            }
            b':' => {
                if let (Some(Open::Object(key)), Some(name)) =
                    (stack.last_mut(), pending_key.take())
                {
                    *key = Some(name);
                }
            }
            b',' => match stack.last_mut() {
                Some(Open::Object(key)) => *key = None,
                Some(Open::Array(index)) => *index = index.saturating_add(1),
                None => {}
            },
            b'{' => stack.push(Open::Object(None)),
            b'[' => stack.push(Open::Array(0)),
            b'}' | b']' => {
                stack.pop();
            }
            _ => {}
        }
    }
    // A key whose string was cut off (`{"t_` ...) is still the field meant.
    if let (Some((content, true)), Some(Open::Object(key))) = (&string, stack.last_mut()) {
        *key = Some(String::from_utf8_lossy(content).into_owned());
    }
    path_of(&stack)
}

fn path_of(stack: &[Open]) -> Option<String> {
    let mut path = String::new();
    for open in stack {
        match open {
            Open::Object(Some(key)) => {
                if !path.is_empty() {
                    path.push('.');
                }
                path.push_str(key);
            }
            // Between members of an object: the path so far is the innermost field.
            Open::Object(None) => break,
            Open::Array(index) => {
                if path.is_empty() {
                    break;
                }
                path.push_str(&format!("[{index}]"));
            }
        }
    }
    (!path.is_empty()).then_some(path)
}

#[cfg(test)]
mod tests {
    use super::field_at;

    fn at_end(text: &str) -> Option<String> {
        field_at(text.as_bytes(), text.len())
    }

    #[test]
    fn names_the_innermost_member_at_the_cut() {
        assert_eq!(
            at_end(r#"{"type":"frame","t_s":0.1"#).as_deref(),
            Some("t_s")
        );
        assert_eq!(
            at_end(r#"{"part_px":[[1.0,2.0],[3.0,"#).as_deref(),
            Some("part_px[1][1]")
        );
        assert_eq!(
            at_end(r#"{"type":"header","camera":{"width":256,"f_px":2"#).as_deref(),
            Some("camera.f_px")
        );
        assert_eq!(
            at_end(r#"{"a":1,"conveyor_angle_rad":NaN"#).as_deref(),
            Some("conveyor_angle_rad")
        );
        // A key cut inside its own string is still named.
        assert_eq!(
            at_end(r#"{"type":"frame","refer"#).as_deref(),
            Some("refer")
        );
        // Strings hold brackets, commas and escaped quotes without confusing the scan.
        assert_eq!(
            at_end(r#"{"note":"a,[b]{\"c\":","t_s":1"#).as_deref(),
            Some("t_s")
        );
        // A closed member no longer counts; before any key there is no field.
        assert_eq!(at_end(r#"{"camera":{"width":1},"#), None);
        assert_eq!(at_end("{"), None);
        assert_eq!(at_end("[1,2"), None);
        assert_eq!(field_at(b"{\"t_s\":1", 100).as_deref(), Some("t_s"));
    }
}
