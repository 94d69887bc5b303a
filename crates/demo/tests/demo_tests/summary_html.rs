//! `summary.html` of the canonical demo (seed 1), parsed as XML: every figure sits inside the
//! section whose text names its SVG file (right after that text, not gathered at the end), the
//! table of contents links every section, and the page loads nothing from elsewhere.

use quick_xml::Reader;
use quick_xml::events::Event;

use crate::common::default_demo;

/// One `<section>` of the page: its id and the text of its own blocks (figures left out).
#[derive(Debug, Default)]
struct Section {
    id: String,
    text: String,
}

/// A figure: its caption (the SVG file name), the id of the innermost section holding it and
/// that section's text before it.
#[derive(Debug)]
struct Figure {
    caption: String,
    section: Option<String>,
    text_before: String,
}

#[test]
fn every_figure_sits_in_the_section_that_names_it() {
    let demo = default_demo();
    let html = &demo.summary_html;
    let mut reader = Reader::from_str(html);
    let mut open: Vec<Section> = Vec::new();
    let mut closed: Vec<Section> = Vec::new();
    let mut figures: Vec<Figure> = Vec::new();
    let mut toc_links: Vec<String> = Vec::new();
    let (mut in_figure, mut in_caption, mut in_nav) = (0usize, false, false);
    let mut caption = String::new();
    loop {
        let event = reader.read_event().unwrap_or_else(|e| {
            panic!("summary.html is not well-formed at byte {}: {e}", reader.buffer_position())
        });
        match event {
            Event::Start(e) => match e.name().as_ref() {
                b"section" => {
                    let id = e
                        .try_get_attribute("id")
                        .expect("attribute")
                        .map(|a| String::from_utf8_lossy(&a.value).into_owned())
                        .expect("a section has an id");
                    open.push(Section { id, text: String::new() });
                }
                b"figure" => {
                    in_figure += 1;
                    caption.clear();
                }
                b"figcaption" => in_caption = true,
                b"nav" => in_nav = true,
                b"a" if in_nav => {
                    if let Some(a) = e.try_get_attribute("href").expect("attribute") {
                        toc_links.push(String::from_utf8_lossy(&a.value).trim_start_matches('#').to_string());
                    }
                }
                b"script" | b"link" | b"img" | b"iframe" => {
                    panic!("external or active content in summary.html")
                }
                _ => {}
            },
            Event::End(e) => match e.name().as_ref() {
                b"section" => closed.push(open.pop().expect("balanced sections")),
                b"figure" => {
                    in_figure -= 1;
                    figures.push(Figure {
                        caption: caption.trim().to_string(),
                        section: open.last().map(|s| s.id.clone()),
                        text_before: open.last().map(|s| s.text.clone()).unwrap_or_default(),
                    });
                }
                b"figcaption" => in_caption = false,
                b"nav" => in_nav = false,
                _ => {}
            },
            Event::Text(t) => {
                let text = t.decode().expect("utf-8").into_owned();
                if in_caption {
                    caption.push_str(&text);
                } else if in_figure == 0
                    && let Some(s) = open.last_mut()
                {
                    s.text.push_str(&text);
                    s.text.push(' ');
                }
            }
            Event::Eof => break,
            _ => {}
        }
    }
    assert!(open.is_empty(), "unclosed sections");
    // the run's plots: the validation histogram and path plots, the convergence plot and one per
    // discovery step, all of them on the page
    let svg_files: Vec<String> = demo
        .out
        .files
        .iter()
        .filter_map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()))
        .filter(|n| n.ends_with(".svg"))
        .collect();
    assert!(svg_files.len() >= 4, "{svg_files:?}");
    let mut captions: Vec<&str> = figures.iter().map(|f| f.caption.as_str()).collect();
    captions.sort_unstable();
    let mut expected: Vec<&str> = svg_files.iter().map(String::as_str).collect();
    expected.sort_unstable();
    assert_eq!(captions, expected, "one figure per SVG file of the run");
    for f in &figures {
        let section = f.section.as_deref().unwrap_or_else(|| panic!("{} outside any section", f.caption));
        assert!(
            f.text_before.contains(&f.caption),
            "figure {} in section `{section}` whose text before it does not name it",
            f.caption
        );
        assert!(!matches!(section, "files" | "other-plots"), "{} gathered in `{section}`", f.caption);
    }
    let sections: Vec<&str> = closed.iter().map(|s| s.id.as_str()).collect();
    for id in &sections {
        assert!(toc_links.iter().any(|l| l == id), "section `{id}` is missing from the contents");
    }
    assert_eq!(toc_links.len(), sections.len());
    for external in ["src=\"http", "href=\"http", "@import", "url("] {
        assert!(!html.contains(external), "{external}");
    }
}
