//! Finding the line of a validation error's field in the TOML text.

/// The 1-based line of a validation field path (`joints[index=3].q_min`, `tcps[1].id`,
/// `inertials.tool.frame`, `format`) in TOML text, found by scanning table headers and keys.
pub(super) fn locate_field(text: &str, field: &str) -> Option<usize> {
    // split "a.b[sel].key[3]" into table segments and the final key
    let mut segs: Vec<&str> = field.split('.').collect();
    let strip = |s: &str| -> (String, Option<String>) {
        match s.split_once('[') {
            Some((name, rest)) => (name.to_string(), Some(rest.trim_end_matches(']').to_string())),
            None => (s.to_string(), None),
        }
    };
    let key = if segs.len() > 1 { segs.pop().map(|k| strip(k).0) } else { None };
    let (last_table, selector) = strip(segs.pop()?);
    let mut table_path: Vec<String> = segs.iter().map(|s| s.to_string()).collect();
    table_path.push(last_table);
    let table = table_path.join(".");
    let lines: Vec<&str> = text.lines().collect();
    let key_of = |line: &str| -> Option<(String, String)> {
        let l = line.trim();
        if l.starts_with('#') || l.starts_with('[') {
            return None;
        }
        let (k, v) = l.split_once('=')?;
        let v = v.split('#').next().unwrap_or("").trim().trim_matches('"');
        Some((k.trim().to_string(), v.to_string()))
    };
    let header = |line: &str| -> Option<String> {
        let l = line.trim();
        let l = l.split('#').next().unwrap_or("").trim();
        l.strip_prefix('[').map(|h| h.trim_start_matches('[').trim_end_matches(']').trim().to_string())
    };
    // top-level key without a table ("format", "version")
    if key.is_none() && selector.is_none() {
        for (i, line) in lines.iter().enumerate() {
            if header(line).is_some() {
                break;
            }
            if key_of(line).is_some_and(|(k, _)| k == table) {
                return Some(i + 1);
            }
        }
    }
    // candidate table bodies: (header line, body lines)
    let mut bodies: Vec<(usize, usize, usize)> = Vec::new(); // (header idx, start, end)
    let mut current: Option<usize> = None;
    for (i, line) in lines.iter().enumerate() {
        if let Some(h) = header(line) {
            if let Some(c) = current.take() {
                bodies.push((c, c + 1, i));
            }
            if h == table {
                current = Some(i);
            }
        }
    }
    if let Some(c) = current {
        bodies.push((c, c + 1, lines.len()));
    }
    let chosen = match selector.as_deref() {
        None => bodies.first().copied(),
        Some(sel) => match sel.split_once('=') {
            Some((sk, sv)) => bodies.iter().copied().find(|(_, a, b)| {
                lines[*a..*b].iter().any(|l| key_of(l).is_some_and(|(k, v)| k == sk && v == sv))
            }),
            None => sel.parse::<usize>().ok().and_then(|k| bodies.get(k).copied()),
        },
    };
    let (h, a, b) = chosen?;
    if let Some(key) = key {
        for (i, line) in lines.iter().enumerate().take(b).skip(a) {
            if key_of(line).is_some_and(|(k, _)| k == key) {
                return Some(i + 1);
            }
        }
    }
    Some(h + 1)
}
