//! Where in a scene file's text a list entry starts, so that an error found after
//! parsing (spawning a body, a tool or a collider) can name its line and column.

/// Line and column (both from 1) of entry `index` of the top-level list `list` (say
/// `bodies`) in the RON text of a scene file; `None` if there is no such entry.
///
/// A small scanner, not a parser: it skips strings and comments, tracks the nesting of
/// brackets, finds `list:` directly inside the outermost parentheses, and counts the
/// entries of the list that follows by the commas at its own depth.
pub fn entry_position(text: &str, list: &str, index: usize) -> Option<(usize, usize)> {
    let chars: Vec<char> = text.chars().collect();
    let (mut line, mut column) = (1usize, 1usize);
    let mut depth = 0usize;
    // the depth of the list's own entries once its `[` is seen
    let mut list_depth: Option<usize> = None;
    let mut expecting_list = false;
    let mut entry = 0usize;
    let mut at_entry_start = false;
    let mut i = 0;
    let advance = |i: &mut usize, line: &mut usize, column: &mut usize| {
        if chars[*i] == '\n' {
            *line += 1;
            *column = 1;
        } else {
            *column += 1;
        }
        *i += 1;
    };
    while i < chars.len() {
        let c = chars[i];
        // comments and strings carry no structure
        if c == '/' && chars.get(i + 1) == Some(&'/') {
            while i < chars.len() && chars[i] != '\n' {
                advance(&mut i, &mut line, &mut column);
            }
            continue;
        }
        if c == '/' && chars.get(i + 1) == Some(&'*') {
            while i < chars.len() && !(chars[i] == '*' && chars.get(i + 1) == Some(&'/')) {
                advance(&mut i, &mut line, &mut column);
            }
            for _ in 0..2 {
                if i < chars.len() {
                    advance(&mut i, &mut line, &mut column);
                }
            }
            continue;
        }
        if c.is_whitespace() {
            advance(&mut i, &mut line, &mut column);
            continue;
        }
        if at_entry_start {
            if c == ']' {
                return None;
            }
            if entry == index {
                return Some((line, column));
            }
            at_entry_start = false;
        }
        match c {
            '"' => {
                advance(&mut i, &mut line, &mut column);
                while i < chars.len() && chars[i] != '"' {
                    if chars[i] == '\\' {
                        advance(&mut i, &mut line, &mut column);
                    }
                    if i < chars.len() {
                        advance(&mut i, &mut line, &mut column);
                    }
                }
            }
            '(' | '[' | '{' => {
                depth += 1;
                if c == '[' && expecting_list {
                    expecting_list = false;
                    list_depth = Some(depth);
                    at_entry_start = true;
                }
            }
            ')' | ']' | '}' => {
                if list_depth == Some(depth) {
                    return None;
                }
                depth = depth.saturating_sub(1);
            }
            ',' if list_depth == Some(depth) => {
                entry += 1;
                at_entry_start = true;
            }
            _ if depth == 1 && list_depth.is_none() && c.is_alphabetic() => {
                let start = i;
                while i < chars.len() && (chars[i].is_alphanumeric() || chars[i] == '_') {
                    advance(&mut i, &mut line, &mut column);
                }
                let word: String = chars[start..i].iter().collect();
                expecting_list = word == list;
                continue;
            }
            _ => {}
        }
        advance(&mut i, &mut line, &mut column);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = r#"// a scene
(
    frames: 10,
    /* "bodies": not this one */
    tools: [(shape: Sphere(radius: 0.1), cut_width: 0.05, path: [])],
    bodies: [
        (shape: Cells(cells: (4, 4, 4)), spacing: 0.1),
        // the second, with a string holding brackets and a comma
        (shape: Mesh(path: "a],(b.obj"), spacing: 0.1),
        (shape: Sphere(radius: 1.0), spacing: 0.1)
    ],
)
"#;

    #[test]
    fn entries_are_found_by_list_and_index() {
        assert_eq!(entry_position(TEXT, "bodies", 0), Some((7, 9)));
        assert_eq!(entry_position(TEXT, "bodies", 1), Some((9, 9)));
        assert_eq!(entry_position(TEXT, "bodies", 2), Some((10, 9)));
        assert_eq!(entry_position(TEXT, "bodies", 3), None);
        assert_eq!(entry_position(TEXT, "tools", 0), Some((5, 13)));
        assert_eq!(entry_position(TEXT, "tools", 1), None);
        assert_eq!(entry_position(TEXT, "colliders", 0), None);
        assert_eq!(entry_position("(bodies: [])", "bodies", 0), None);
    }
}
