#!/usr/bin/env python3
"""Checks a `summary.html` as a real browser builds it (the manual check of docs/report.md).

    chromium --headless ... --dump-dom file:///abs/path/summary.html > dom.html
    scripts/check-summary-html.py dom.html

Reads the DOM that Chromium serialised (`--dump-dom`), and checks that every `<figure>` sits
inside a `<section>` whose text before the figure names the figure's caption (the SVG file
name), that the table of contents links every section, and that nothing is loaded from
elsewhere. Prints one line per figure (section id, caption) and exits 1 on a failure.
Standard library only.
"""

import sys
from html.parser import HTMLParser


class Dom(HTMLParser):
    def __init__(self):
        super().__init__()
        self.sections = []  # open: [id, text]
        self.ids = []
        self.figures = []  # (caption, section id, text before)
        self.toc = []
        self.in_nav = self.in_caption = False
        self.in_figure = 0
        self.caption = ""
        self.external = []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if tag == "section":
            self.sections.append([a.get("id", ""), ""])
            self.ids.append(a.get("id", ""))
        elif tag == "figure":
            self.in_figure += 1
            self.caption = ""
        elif tag == "figcaption":
            self.in_caption = True
        elif tag == "nav":
            self.in_nav = True
        elif tag == "a" and self.in_nav:
            self.toc.append(a.get("href", "").lstrip("#"))
        if tag in ("script", "link", "img", "iframe") or any(
            (v or "").startswith(("http:", "https:", "//")) for k, v in attrs if k in ("src", "href")
        ):
            self.external.append(tag)

    def handle_endtag(self, tag):
        if tag == "section":
            self.sections.pop()
        elif tag == "figure":
            self.in_figure -= 1
            s = self.sections[-1] if self.sections else None
            self.figures.append((self.caption.strip(), s[0] if s else None, s[1] if s else ""))
        elif tag == "figcaption":
            self.in_caption = False
        elif tag == "nav":
            self.in_nav = False

    def handle_data(self, data):
        if self.in_caption:
            self.caption += data
        elif self.in_figure == 0 and self.sections:
            self.sections[-1][1] += data + " "


def main():
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    dom = Dom()
    dom.feed(open(sys.argv[1], encoding="utf-8").read())
    failures = []
    if not dom.figures:
        failures.append("no figure at all")
    for caption, section, before in dom.figures:
        print(f"{section or '(no section)':<60} {caption}")
        if section is None:
            failures.append(f"{caption}: outside any section")
        elif caption not in before:
            failures.append(f"{caption}: section `{section}` does not name it before the figure")
        elif section in ("files", "other-plots"):
            failures.append(f"{caption}: gathered in `{section}`")
    missing = [i for i in dom.ids if i not in dom.toc]
    if missing:
        failures.append(f"sections missing from the contents: {missing}")
    if dom.external:
        failures.append(f"external or active content: {dom.external}")
    for f in failures:
        print("FAIL", f, file=sys.stderr)
    print(f"{len(dom.figures)} figures in {len(dom.ids)} sections; {len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
