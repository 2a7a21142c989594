//! Array names as they are shown to people. A name comes from a file and may be anything: a
//! megabyte long, or full of terminal escape sequences. It is kept exactly as read (so that
//! `--array` can name it) and shown through [`shown_name`]: control and invisible formatting
//! characters escaped, and long names cut with an ellipsis and their full length stated.

/// Characters of a name shown before it is cut.
pub const SHOWN_NAME_CHARS: usize = 60;

/// Names of a list shown before the rest is counted.
pub const SHOWN_LIST_NAMES: usize = 8;

/// Whether `c` would act on a terminal or reorder text instead of being seen: control
/// characters (C0, DEL, C1: escape sequences start here) and the bidirectional and zero-width
/// formatting characters.
fn hidden(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}' | '\u{feff}')
}

/// `name` safe to print: hidden characters written as escapes (`\u{1b}`, `\n`), at most
/// [`SHOWN_NAME_CHARS`] characters of it, then `…` and the full length when it is longer.
pub fn shown_name(name: &str) -> String {
    let mut out = String::new();
    for (i, c) in name.chars().enumerate() {
        if i == SHOWN_NAME_CHARS {
            let n = name.chars().count();
            out.push_str(&format!("… ({n} characters)"));
            break;
        }
        if hidden(c) {
            out.extend(c.escape_debug());
        } else {
            out.push(c);
        }
    }
    out
}

/// Names for a message, comma separated, each through [`shown_name`]: the first
/// [`SHOWN_LIST_NAMES`], then how many more there are.
pub fn shown_list<'a>(names: impl ExactSizeIterator<Item = &'a str>) -> String {
    let total = names.len();
    let mut parts: Vec<String> = names.take(SHOWN_LIST_NAMES).map(shown_name).collect();
    if total > SHOWN_LIST_NAMES {
        parts.push(format!("and {} more", total - SHOWN_LIST_NAMES));
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escapes_reach_no_terminal_and_long_names_are_cut() {
        assert_eq!(shown_name("pressure"), "pressure");
        assert_eq!(shown_name("a\u{1b}[2Jb\n"), "a\\u{1b}[2Jb\\n");
        assert_eq!(shown_name("x\u{202e}y"), "x\\u{202e}y");
        let long = "é".repeat(70_000);
        let s = shown_name(&long);
        assert_eq!(s, format!("{}… (70000 characters)", "é".repeat(60)));
        assert!(!shown_name(&"\u{7}".repeat(1000)).contains('\u{7}'));
    }

    #[test]
    fn long_lists_are_counted() {
        let names: Vec<String> = (0..10).map(|i| format!("a{i}")).collect();
        assert_eq!(
            shown_list(names.iter().map(String::as_str)),
            "a0, a1, a2, a3, a4, a5, a6, a7, and 2 more"
        );
        assert_eq!(shown_list(["q"].into_iter()), "q");
    }
}
