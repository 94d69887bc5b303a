//! A small builder of self-contained HTML reports: one file, inline CSS and SVGs, no scripts and
//! no external resources, readable offline in any browser.
//!
//! Every heading opens a `<section id="…">` that holds what follows it up to the next heading
//! of the same or a higher level (a level-3 heading's section nests in its level-2 one), so a
//! figure added after a paragraph sits in that paragraph's section; a table of contents of
//! links to the sections follows the title when the document has two headings or more. The
//! document is also well-formed XML (void elements are self-closed), so it can be checked
//! with an XML parser.
//!
//! ```
//! use vatcal_report::html::HtmlReport;
//! let mut r = HtmlReport::new("Discovery");
//! r.heading("Result")
//!     .paragraph("Added **joint-cyclic** (joint 4): gap `0.041` -> `0.008` mm.")
//!     .table(&["effect", "gap after [mm]"], &[vec!["joint-cyclic".into(), "0.0084".into()]]);
//! let html = r.render();
//! assert!(html.starts_with("<!DOCTYPE html>") && html.contains("<strong>joint-cyclic</strong>"));
//! ```
//!
//! Text passes through [`escape`] first, then a markdown-ish subset is applied to paragraphs:
//! `**bold**`, `` `code` `` and blank-line separated paragraphs. SVGs are inserted verbatim
//! (they come from this crate's plot functions); a leading XML declaration is dropped.

use std::fmt::Write;
use std::path::Path;

use crate::PlotError;

/// One block of the document.
#[derive(Debug, Clone, PartialEq)]
enum Block {
    Heading { level: u8, text: String },
    Paragraph(String),
    Preformatted(String),
    Table { header: Vec<String>, rows: Vec<Vec<String>> },
    Svg { svg: String, caption: String },
}

/// A self-contained HTML document built block by block (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct HtmlReport {
    title: String,
    blocks: Vec<Block>,
}

/// Escapes `&`, `<`, `>`, `"` and `'` for HTML text and attributes.
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            _ => out.push(c),
        }
    }
    out
}

/// Escapes `text` and applies `**bold**` and `` `code` `` (unbalanced markers stay literal).
pub fn inline_markup(text: &str) -> String {
    let escaped = escape(text);
    let bold = toggle(&escaped, "**", "strong");
    toggle(&bold, "`", "code")
}

/// Replaces balanced pairs of `marker` by `<tag>`…`</tag>`.
fn toggle(text: &str, marker: &str, tag: &str) -> String {
    let parts: Vec<&str> = text.split(marker).collect();
    if parts.len() < 3 {
        return text.to_string();
    }
    let pairs = (parts.len() - 1) / 2;
    let mut out = String::with_capacity(text.len() + 16 * pairs);
    for (k, part) in parts.iter().enumerate() {
        if k > 0 {
            if k <= 2 * pairs {
                out.push_str(if k % 2 == 1 { "<" } else { "</" });
                out.push_str(tag);
                out.push('>');
            } else {
                out.push_str(marker);
            }
        }
        out.push_str(part);
    }
    out
}

/// Drops an XML declaration / doctype before the `<svg` element.
fn inline_svg(svg: &str) -> &str {
    svg.find("<svg").map_or(svg, |k| &svg[k..])
}

const STYLE: &str = "body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;\
max-width:60rem;margin:2rem auto;padding:0 1rem;color:#222;line-height:1.45}\
h1{font-size:1.6rem;border-bottom:2px solid #ccc}h2{font-size:1.25rem;margin-top:2rem}\
table{border-collapse:collapse;margin:1rem 0}th,td{border:1px solid #bbb;padding:.25rem .6rem;\
text-align:left;vertical-align:top}th{background:#f0f0f0}code,pre{background:#f6f6f6;\
font-family:ui-monospace,Menlo,Consolas,monospace}pre{padding:.6rem;overflow-x:auto}\
figure{margin:1rem 0}figcaption{font-size:.9rem;color:#555}svg{max-width:100%;height:auto}\
h3{font-size:1.05rem;margin-top:1.5rem}nav.toc{background:#f8f8f8;border:1px solid #ddd;\
padding:.4rem 1rem;margin:1rem 0}nav.toc h2{font-size:1rem;margin:.3rem 0}nav.toc ul{margin:.2rem 0;\
padding-left:1.2rem}nav.toc a{text-decoration:none}";

/// An `id` for a heading: lower-case letters and digits of `text` joined by `-`, made unique
/// among `taken` by a numeric suffix.
fn slug(text: &str, taken: &[String]) -> String {
    let mut base = String::new();
    for c in text.chars() {
        if c.is_ascii_alphanumeric() {
            base.push(c.to_ascii_lowercase());
        } else if !base.is_empty() && !base.ends_with('-') {
            base.push('-');
        }
    }
    let base = match base.trim_end_matches('-') {
        "" => "section".to_string(),
        b => b.to_string(),
    };
    let mut id = base.clone();
    let mut k = 2;
    while taken.contains(&id) {
        id = format!("{base}-{k}");
        k += 1;
    }
    id
}

impl HtmlReport {
    /// An empty document with a title (shown as the page title and the first heading).
    pub fn new(title: impl Into<String>) -> Self {
        Self { title: title.into(), blocks: Vec::new() }
    }

    /// A section heading (`<h2>`): opens a section that ends at the next section heading.
    pub fn heading(&mut self, text: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Heading { level: 2, text: text.into() });
        self
    }

    /// A subsection heading (`<h3>`): opens a subsection of the current section that ends at
    /// the next heading of either level.
    pub fn subheading(&mut self, text: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Heading { level: 3, text: text.into() });
        self
    }

    /// Text: blank lines separate paragraphs, single line breaks are kept as spaces;
    /// `**bold**` and `` `code` `` are rendered.
    pub fn paragraph(&mut self, text: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Paragraph(text.into()));
        self
    }

    /// Monospaced text shown as is (e.g. a command's text output).
    pub fn preformatted(&mut self, text: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Preformatted(text.into()));
        self
    }

    /// A table; cells use the inline markup of [`HtmlReport::paragraph`]. Rows shorter than
    /// the header are padded with empty cells.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) -> &mut Self {
        self.blocks.push(Block::Table {
            header: header.iter().map(|s| s.to_string()).collect(),
            rows: rows.to_vec(),
        });
        self
    }

    /// An inline SVG figure with a caption.
    pub fn svg(&mut self, svg: impl Into<String>, caption: impl Into<String>) -> &mut Self {
        self.blocks.push(Block::Svg { svg: svg.into(), caption: caption.into() });
        self
    }

    /// The complete document: title, table of contents (two headings or more), then the
    /// blocks, each heading opening a `<section>`.
    pub fn render(&self) -> String {
        let mut out = String::new();
        let title = escape(&self.title);
        let _ = write!(
            out,
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\" />\n\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\" />\n\
             <title>{title}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{title}</h1>\n"
        );
        let mut ids: Vec<String> = Vec::new();
        for block in &self.blocks {
            if let Block::Heading { text, .. } = block {
                let id = slug(text, &ids);
                ids.push(id);
            }
        }
        let headings: Vec<(u8, &str)> = self
            .blocks
            .iter()
            .filter_map(|b| match b {
                Block::Heading { level, text } => Some((*level, text.as_str())),
                _ => None,
            })
            .collect();
        if headings.len() >= 2 {
            out.push_str("<nav class=\"toc\">\n<h2>Contents</h2>\n<ul>\n");
            let mut in_sub = false;
            for (k, ((level, text), id)) in headings.iter().zip(&ids).enumerate() {
                if *level > 2 && !in_sub && k > 0 {
                    out.push_str("<ul>\n");
                    in_sub = true;
                } else if *level <= 2 && in_sub {
                    out.push_str("</li>\n</ul></li>\n");
                    in_sub = false;
                } else if k > 0 {
                    out.push_str("</li>\n");
                }
                let _ = write!(out, "<li><a href=\"#{id}\">{}</a>", inline_markup(text));
            }
            out.push_str(if in_sub { "</li>\n</ul></li>\n" } else { "</li>\n" });
            out.push_str("</ul>\n</nav>\n");
        }
        // levels of the open sections
        let mut open: Vec<u8> = Vec::new();
        let mut next_id = ids.iter();
        for block in &self.blocks {
            match block {
                Block::Heading { level, text } => {
                    while open.last().is_some_and(|l| l >= level) {
                        open.pop();
                        out.push_str("</section>\n");
                    }
                    open.push(*level);
                    let id = next_id.next().map_or("section", String::as_str);
                    let _ =
                        writeln!(out, "<section id=\"{id}\">\n<h{level}>{}</h{level}>", inline_markup(text));
                }
                Block::Paragraph(t) => {
                    for para in t.split("\n\n").map(str::trim).filter(|p| !p.is_empty()) {
                        let joined: Vec<&str> = para.lines().map(str::trim).collect();
                        let _ = writeln!(out, "<p>{}</p>", inline_markup(&joined.join(" ")));
                    }
                }
                Block::Preformatted(t) => {
                    let _ = writeln!(out, "<pre>{}</pre>", escape(t));
                }
                Block::Table { header, rows } => {
                    out.push_str("<table>\n<thead><tr>");
                    for h in header {
                        let _ = write!(out, "<th>{}</th>", inline_markup(h));
                    }
                    out.push_str("</tr></thead>\n<tbody>\n");
                    for row in rows {
                        out.push_str("<tr>");
                        for k in 0..header.len().max(row.len()) {
                            let cell = row.get(k).map_or(String::new(), |c| inline_markup(c));
                            let _ = write!(out, "<td>{cell}</td>");
                        }
                        out.push_str("</tr>\n");
                    }
                    out.push_str("</tbody>\n</table>\n");
                }
                Block::Svg { svg, caption } => {
                    let _ = writeln!(
                        out,
                        "<figure>\n{}\n<figcaption>{}</figcaption>\n</figure>",
                        inline_svg(svg),
                        inline_markup(caption)
                    );
                }
            }
        }
        for _ in open {
            out.push_str("</section>\n");
        }
        out.push_str("</body>\n</html>\n");
        out
    }

    /// Writes the document to `path`.
    ///
    /// # Examples
    /// ```
    /// use vatcal_report::html::HtmlReport;
    ///
    /// let mut page = HtmlReport::new("Calibration <cell 1>");
    /// page.heading("Result")
    ///     .paragraph("mean error **0.015 mm**")
    ///     .table(&["model", "mean [mm]"], &[vec!["calibrated".into(), "0.015".into()]]);
    /// let path = std::env::temp_dir().join(format!("vatcal-doc-report-{}.html", std::process::id()));
    /// page.save(&path)?;
    /// let html = std::fs::read_to_string(&path)?;
    /// std::fs::remove_file(&path)?;
    /// assert!(html.contains("Calibration &lt;cell 1&gt;") && html.contains("<strong>0.015 mm</strong>"));
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    /// [`PlotError::File`] when the file cannot be written (naming the path).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), PlotError> {
        let path = path.as_ref();
        std::fs::write(path, self.render())
            .map_err(|source| PlotError::File { path: path.to_path_buf(), source })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_before_markup() {
        assert_eq!(
            inline_markup("a <b> & **c** `d<e`"),
            "a &lt;b&gt; &amp; <strong>c</strong> <code>d&lt;e</code>"
        );
        // an unbalanced marker stays literal
        assert_eq!(inline_markup("x ** y"), "x ** y");
        assert_eq!(inline_markup("**a** **b"), "<strong>a</strong> **b");
    }

    #[test]
    fn document_is_self_contained_and_holds_every_block() {
        let svg = crate::line_plot_svg(
            &crate::PlotSpec::new("t", "x", "y"),
            &[0.0, 1.0, 2.0],
            &[crate::Series::new("s", &[1.0, 2.0, 1.5])],
        )
        .expect("plot");
        let mut r = HtmlReport::new("T <1>");
        r.heading("H")
            .paragraph("one\nline\n\nsecond")
            .preformatted("a < b")
            .table(&["a", "b"], &[vec!["1".into()], vec!["**2**".into(), "3".into()]])
            .svg(svg, "cap");
        let html = r.render();
        assert!(html.contains("<title>T &lt;1&gt;</title>"));
        assert!(html.contains("<p>one line</p>\n<p>second</p>"));
        assert!(html.contains("<pre>a &lt; b</pre>"));
        assert!(html.contains("<tr><td>1</td><td></td></tr>"));
        assert!(html.contains("<td><strong>2</strong></td>"));
        assert_eq!(html.matches("<svg").count(), 1);
        assert!(html.contains("<figcaption>cap</figcaption>"));
        // nothing is loaded from elsewhere
        for external in ["<script", "<link", "src=\"http", "href=\"http", "@import", "url("] {
            assert!(!html.contains(external), "{external}");
        }
        assert!(!html.contains("<?xml"));
    }

    #[test]
    fn headings_open_nested_sections_listed_in_the_contents() {
        let mut r = HtmlReport::new("T");
        r.heading("Setup & data")
            .paragraph("a")
            .subheading("Probe")
            .svg("<svg></svg>", "probe plot")
            .subheading("Probe")
            .heading("Result")
            .paragraph("b");
        let html = r.render();
        let toc = "<nav class=\"toc\">\n<h2>Contents</h2>\n<ul>\n<li><a href=\"#setup-data\">Setup &amp; data</a><ul>\n\
                   <li><a href=\"#probe\">Probe</a></li>\n<li><a href=\"#probe-2\">Probe</a></li>\n</ul></li>\n\
                   <li><a href=\"#result\">Result</a></li>\n</ul>\n</nav>\n";
        assert!(html.contains(toc), "{html}");
        let body = "<section id=\"setup-data\">\n<h2>Setup &amp; data</h2>\n<p>a</p>\n\
                    <section id=\"probe\">\n<h3>Probe</h3>\n<figure>\n<svg></svg>\n<figcaption>probe plot</figcaption>\n</figure>\n\
                    </section>\n<section id=\"probe-2\">\n<h3>Probe</h3>\n</section>\n</section>\n\
                    <section id=\"result\">\n<h2>Result</h2>\n<p>b</p>\n</section>\n</body>";
        assert!(html.contains(body), "{html}");
        // one heading: no contents
        let mut one = HtmlReport::new("T");
        one.heading("Only");
        assert!(!one.render().contains("<nav"));
        assert_eq!(slug("  ", &[]), "section");
        assert_eq!(
            slug("Printing by `vatcal compensate`'s targets", &[]),
            "printing-by-vatcal-compensate-s-targets"
        );
    }
}
