"""The fleet page's style sheet and script (sortable tables, bogie order), inline so that the
page opens from disk with no server and nothing fetched."""

STYLE = """
body { font: 14px/1.4 system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { margin-bottom: 0.2em; } h2 { border-bottom: 2px solid #ccc; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.5em 0 1em; }
th, td { padding: 3px 9px; border-bottom: 1px solid #e4e4e4; text-align: left; }
th { cursor: pointer; background: #f3f3f3; user-select: none; }
th[data-dir=asc]::after { content: " \\25B2"; } th[data-dir=desc]::after { content: " \\25BC"; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
.failed { color: #b00020; font-weight: 600; } .degraded { color: #d35400; font-weight: 600; }
.watch { color: #b7950b; font-weight: 600; } .healthy { color: #1e7b34; }
.not-identifiable, .muted { color: #7f8c8d; }
section.bogie { border: 1px solid #ddd; border-radius: 6px; padding: 0 1em 1em; margin: 1em 0; }
svg.chart { font: 11px system-ui, sans-serif; margin: 4px 8px 4px 0; background: #fff; }
.trends { display: flex; flex-wrap: wrap; }
.legend span { margin-right: 1.2em; }
"""

SCRIPT = """
(function () {
  var NUMBER = /^[-+]?[0-9]*[.]?[0-9]+([eE][-+]?[0-9]+)?$/;
  function key(cell) {
    var v = cell.getAttribute("data-sort");
    if (v === null) { v = cell.textContent.trim(); }
    return NUMBER.test(v) ? { n: parseFloat(v), s: v } : { n: null, s: v.toLowerCase() };
  }
  function compare(a, b) {
    if (a.n !== null && b.n !== null) { return a.n - b.n; }
    return a.s < b.s ? -1 : a.s > b.s ? 1 : 0;
  }
  function sortTable(table, col, th) {
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    var dir = th.getAttribute("data-dir") === "asc" ? "desc" : "asc";
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (c) {
      c.removeAttribute("data-dir");
    });
    th.setAttribute("data-dir", dir);
    rows.sort(function (a, b) {
      var r = compare(key(a.cells[col]), key(b.cells[col]));
      return dir === "asc" ? r : -r;
    });
    rows.forEach(function (r) { body.appendChild(r); });
  }
  Array.prototype.forEach.call(document.querySelectorAll("table.sortable"), function (table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, col) {
      th.addEventListener("click", function () { sortTable(table, col, th); });
    });
  });
  var order = document.getElementById("bogie-order");
  if (order) {
    order.addEventListener("change", function () {
      var holder = document.getElementById("bogie-sections");
      var items = Array.prototype.slice.call(holder.children);
      var by = order.value;
      items.sort(function (a, b) {
        var x = a.getAttribute("data-" + by), y = b.getAttribute("data-" + by);
        return by === "date" ? (x < y ? 1 : x > y ? -1 : 0) : (x < y ? -1 : x > y ? 1 : 0);
      });
      items.forEach(function (s) { holder.appendChild(s); });
    });
  }
  document.body.setAttribute("data-ready", "yes");
})();
"""
