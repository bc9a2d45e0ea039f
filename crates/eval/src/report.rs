//! The HTML report: one self-contained page (inline style, no network) that shows an
//! experiment's sections, each with its text, figures (PNG files beside the page, by relative
//! path), rows of images side by side, and tables.
//!
//! A small script at the end records on `<body>` how many images loaded
//! (`data-images-loaded`, `data-images-total`), so that a headless browser can check that the
//! page shows what it links.

use std::fmt::Write as _;
use std::path::Path;

/// A whole report.
#[derive(Debug, Clone, Default)]
pub struct Report {
    pub title: String,
    pub subtitle: String,
    pub sections: Vec<Section>,
}

/// A titled part of the report.
#[derive(Debug, Clone, Default)]
pub struct Section {
    pub title: String,
    pub text: String,
    /// Figures laid out in a wrapping grid (charts).
    pub figures: Vec<Figure>,
    /// Rows of figures kept side by side (an image next to its reference and error map).
    pub rows: Vec<Vec<Figure>>,
    pub tables: Vec<Table>,
}

/// An image file, relative to the report, and its caption.
#[derive(Debug, Clone, PartialEq)]
pub struct Figure {
    pub path: String,
    pub caption: String,
    /// Display width in CSS pixels, upscaled without smoothing (so that pixels and noise stay
    /// visible); `None`: the file's own width, at most the page's.
    pub display_width: Option<u32>,
}

/// A table of text cells.
#[derive(Debug, Clone, Default)]
pub struct Table {
    pub caption: String,
    pub headers: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

const STYLE: &str = r#"
body { font-family: system-ui, -apple-system, "Segoe UI", Ubuntu, sans-serif; margin: 0 auto;
       max-width: 1320px; padding: 1.5em 2em 4em; color: #1d1d1f; background: #fff; }
h1 { margin-bottom: 0.2em; }
.subtitle { color: #444; max-width: 70em; white-space: pre-line; }
nav { margin: 1em 0 2em; padding: 0.6em 1em; background: #f4f5f7; border-radius: 6px; }
nav a { margin-right: 1.2em; color: #1f5fa8; text-decoration: none; }
section { margin-top: 2.5em; border-top: 1px solid #ddd; padding-top: 0.5em; }
.gallery { display: flex; flex-wrap: wrap; gap: 1.2em; align-items: flex-start; }
.row { display: flex; gap: 0.8em; overflow-x: auto; margin-bottom: 1em; align-items: flex-start; }
figure { margin: 0; }
figure img { display: block; max-width: 100%; border: 1px solid #e2e2e2; }
.gallery figure { flex: 1 1 520px; max-width: 640px; }
.gallery figure img { width: 100%; height: auto; }
img.pixels { image-rendering: pixelated; max-width: none; }
figcaption { font-size: 0.85em; color: #555; margin-top: 0.3em; max-width: 28em; }
table { border-collapse: collapse; margin: 1em 0; font-size: 0.9em; }
caption { text-align: left; font-weight: 600; padding-bottom: 0.4em; }
th, td { border: 1px solid #d5d5d5; padding: 0.25em 0.6em; text-align: right; }
th { background: #f4f5f7; }
td:first-child, th:first-child { text-align: left; }
"#;

const SCRIPT: &str = r#"
window.addEventListener("load", function () {
  var imgs = Array.prototype.slice.call(document.images);
  var ok = imgs.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;
  document.body.setAttribute("data-images-loaded", String(ok));
  document.body.setAttribute("data-images-total", String(imgs.length));
});
"#;

/// Escapes text for HTML content and attribute values.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
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

/// A relative path as a URL path: each segment percent-encoded except unreserved characters.
fn url_path(path: &str) -> String {
    path.split('/')
        .map(|seg| {
            let mut out = String::new();
            for b in seg.bytes() {
                if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
                    out.push(b as char);
                } else {
                    let _ = write!(out, "%{b:02X}");
                }
            }
            out
        })
        .collect::<Vec<_>>()
        .join("/")
}

fn anchor(index: usize) -> String {
    format!("s{index}")
}

fn figure_html(f: &Figure, out: &mut String) {
    let src = escape(&url_path(&f.path));
    let caption = escape(&f.caption);
    let img = match f.display_width {
        Some(w) => {
            format!(r#"<img class="pixels" src="{src}" alt="{caption}" style="width:{w}px">"#)
        }
        None => format!(r#"<img src="{src}" alt="{caption}">"#),
    };
    let _ = writeln!(
        out,
        "<figure><a href=\"{src}\">{img}</a><figcaption>{caption}</figcaption></figure>"
    );
}

fn table_html(t: &Table, out: &mut String) {
    out.push_str("<table>\n");
    if !t.caption.is_empty() {
        let _ = writeln!(out, "<caption>{}</caption>", escape(&t.caption));
    }
    out.push_str("<thead><tr>");
    for h in &t.headers {
        let _ = write!(out, "<th>{}</th>", escape(h));
    }
    out.push_str("</tr></thead>\n<tbody>\n");
    for row in &t.rows {
        out.push_str("<tr>");
        for cell in row {
            let _ = write!(out, "<td>{}</td>", escape(cell));
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody></table>\n");
}

/// The report as one HTML page.
pub fn render_html(report: &Report) -> String {
    let mut out = String::new();
    let _ = write!(
        out,
        "<!doctype html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n\
         <title>{}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n<h1>{}</h1>\n",
        escape(&report.title),
        escape(&report.title)
    );
    if !report.subtitle.is_empty() {
        let _ = writeln!(
            out,
            "<p class=\"subtitle\">{}</p>",
            escape(&report.subtitle)
        );
    }
    out.push_str("<nav>");
    for (i, s) in report.sections.iter().enumerate() {
        let _ = write!(out, "<a href=\"#{}\">{}</a>", anchor(i), escape(&s.title));
    }
    out.push_str("</nav>\n");
    for (i, s) in report.sections.iter().enumerate() {
        let _ = writeln!(
            out,
            "<section id=\"{}\">\n<h2>{}</h2>",
            anchor(i),
            escape(&s.title)
        );
        if !s.text.is_empty() {
            let _ = writeln!(out, "<p>{}</p>", escape(&s.text));
        }
        for t in &s.tables {
            table_html(t, &mut out);
        }
        if !s.figures.is_empty() {
            out.push_str("<div class=\"gallery\">\n");
            for f in &s.figures {
                figure_html(f, &mut out);
            }
            out.push_str("</div>\n");
        }
        for row in &s.rows {
            out.push_str("<div class=\"row\">\n");
            for f in row {
                figure_html(f, &mut out);
            }
            out.push_str("</div>\n");
        }
        out.push_str("</section>\n");
    }
    let _ = write!(out, "<script>{SCRIPT}</script>\n</body>\n</html>\n");
    out
}

/// Writes the report to `path` atomically.
pub fn write_html(
    report: &Report,
    path: &Path,
) -> Result<(), pathlight_render::output::OutputError> {
    pathlight_render::output::write_atomic(path, render_html(report).as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_escaped_and_paths_are_urls() {
        let report = Report {
            title: "a <b> & \"c\"".into(),
            subtitle: String::new(),
            sections: vec![Section {
                title: "S".into(),
                text: "x < y".into(),
                figures: vec![Figure {
                    path: "plots/m&m #1.png".into(),
                    caption: "<script>".into(),
                    display_width: None,
                }],
                rows: vec![vec![Figure {
                    path: "images/a.png".into(),
                    caption: "a".into(),
                    display_width: Some(256),
                }]],
                tables: vec![Table {
                    caption: "t".into(),
                    headers: vec!["h".into()],
                    rows: vec![vec!["</td>".into()]],
                }],
            }],
        };
        let html = render_html(&report);
        assert!(html.contains("<h1>a &lt;b&gt; &amp; &quot;c&quot;</h1>"));
        assert!(html.contains("<p>x &lt; y</p>"));
        assert!(html.contains("src=\"plots/m%26m%20%231.png\""));
        assert!(html.contains("alt=\"&lt;script&gt;\""));
        assert!(html.contains("<td>&lt;/td&gt;</td>"));
        assert!(html.contains("class=\"pixels\" src=\"images/a.png\""));
        assert!(html.contains("style=\"width:256px\""));
        assert!(html.contains("href=\"#s0\""));
        // Exactly one script: the image counter.
        assert_eq!(html.matches("<script>").count(), 1);
    }
}
