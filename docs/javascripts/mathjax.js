// MathJax 3 configuration for pymdownx.arithmatex (generic mode): typeset only the
// .arithmatex spans and divs, with \( \) inline and \[ \] display delimiters.
window.MathJax = {
  tex: {
    inlineMath: [["\\(", "\\)"]],
    displayMath: [["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true,
  },
  options: {
    ignoreHtmlClass: ".*|",
    processHtmlClass: "arithmatex",
  },
};
// The theme's instant navigation is off (mkdocs.yml), so every page is a full load and
// MathJax typesets it once on startup. (Re-typesetting on Material's document$ signal
// as well would clear MathJax's per-glyph CSS after the first pass and blank the math.)
