//! `summary.html`: `summary.md` as one self-contained page with the run's plots inline.

use std::path::Path;

use crate::PipelineError;
use crate::folders::{SUMMARY_HTML, SUMMARY_MD};

/// `summary.html`: the text of `summary.md` as one self-contained page (headings as nested
/// sections with a table of contents, tables, code blocks, paragraphs), each SVG plot of the
/// run (`(file name, svg)`) inline right after the first paragraph, list item or table that
/// names its file — beside the text it illustrates; a plot the text never names goes to a last
/// section "Other plots".
pub fn summary_html(markdown: &str, svgs: &[(String, String)]) -> vatcal_report::html::HtmlReport {
    use vatcal_report::html::HtmlReport;
    let mut lines = markdown.lines().peekable();
    let title = lines.peek().map_or("vatcal", |l| l.trim_start_matches('#').trim()).to_string();
    lines.next();
    let mut r = HtmlReport::new(title);
    let mut placed = vec![false; svgs.len()];
    // the plots `text` names (not placed yet), as figures after it
    let mut figures = |r: &mut HtmlReport, text: &str| {
        for ((name, svg), done) in svgs.iter().zip(placed.iter_mut()) {
            if !*done && text.contains(name.as_str()) {
                r.svg(svg.clone(), name.clone());
                *done = true;
            }
        }
    };
    let mut para = String::new();
    let flush = |r: &mut HtmlReport, para: &mut String, figures: &mut dyn FnMut(&mut HtmlReport, &str)| {
        if !para.trim().is_empty() {
            r.paragraph(para.trim().to_string());
            figures(r, para);
        }
        para.clear();
    };
    let cells = |l: &str| -> Vec<String> {
        l.trim().trim_matches('|').split('|').map(|c| c.trim().to_string()).collect()
    };
    while let Some(line) = lines.next() {
        if let Some(h) = line.strip_prefix('#') {
            flush(&mut r, &mut para, &mut figures);
            let text = h.trim_start_matches('#').trim();
            if h.starts_with('#') {
                r.subheading(text);
            } else {
                r.heading(text);
            }
        } else if line.starts_with("```") {
            flush(&mut r, &mut para, &mut figures);
            let mut block = String::new();
            for l in lines.by_ref() {
                if l.starts_with("```") {
                    break;
                }
                block.push_str(l);
                block.push('\n');
            }
            r.preformatted(block.clone());
            figures(&mut r, &block);
        } else if line.starts_with('|') {
            flush(&mut r, &mut para, &mut figures);
            let header = cells(line);
            let mut rows = Vec::new();
            let mut text = line.to_string();
            while let Some(l) = lines.peek() {
                if !l.starts_with('|') {
                    break;
                }
                let row = cells(l);
                if !row.iter().all(|c| c.chars().all(|ch| matches!(ch, '-' | ':'))) {
                    rows.push(row);
                }
                text.push_str(l);
                lines.next();
            }
            let h: Vec<&str> = header.iter().map(String::as_str).collect();
            r.table(&h, &rows);
            figures(&mut r, &text);
        } else if line.starts_with("* ") {
            flush(&mut r, &mut para, &mut figures);
            r.paragraph(line.to_string());
            figures(&mut r, line);
        } else if line.trim().is_empty() {
            flush(&mut r, &mut para, &mut figures);
        } else {
            para.push_str(line);
            para.push('\n');
        }
    }
    flush(&mut r, &mut para, &mut figures);
    let rest: Vec<&(String, String)> =
        svgs.iter().zip(&placed).filter(|(_, done)| !**done).map(|(s, _)| s).collect();
    if !rest.is_empty() {
        r.heading("Other plots");
        for (name, svg) in rest {
            r.svg(svg.clone(), name.clone());
        }
    }
    r
}

/// Writes `summary.html` from `summary.md` and the SVG files of the run folder `out`.
pub(crate) fn write_summary_html(out: &Path) -> Result<(), PipelineError> {
    let read = |path: std::path::PathBuf| {
        std::fs::read_to_string(&path).map_err(|source| PipelineError::Io { path, source })
    };
    let markdown = read(out.join(SUMMARY_MD))?;
    let mut names: Vec<String> = std::fs::read_dir(out)
        .map_err(|source| PipelineError::Io { path: out.to_path_buf(), source })?
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".svg"))
        .collect();
    names.sort();
    let mut svgs = Vec::new();
    for n in names {
        let svg = read(out.join(&n))?;
        svgs.push((n, svg));
    }
    summary_html(&markdown, &svgs).save(out.join(SUMMARY_HTML))?;
    Ok(())
}
