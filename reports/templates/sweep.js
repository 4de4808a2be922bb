/* The sweep report's script (inlined, no network): a link into a collapsed section opens it;
   the tables of class "sortable" sort by a column on a click of its header; the filters of
   a ".filters" block hide the rows of their table that do not match. */
(function () {
  "use strict";
  function reveal(id) {
    var el = id && document.getElementById(id);
    if (!el) return;
    for (var p = el; p; p = p.parentElement) {
      if (p.tagName === "DETAILS") p.open = true;
    }
    if (el.tagName === "TR") {
      el.classList.add("target");
      setTimeout(function () { el.classList.remove("target"); }, 2500);
    }
    el.scrollIntoView({ block: "center" });
  }
  function fromHash() { reveal(decodeURIComponent(location.hash.slice(1))); }
  window.addEventListener("hashchange", fromHash);
  document.addEventListener("click", function (ev) {
    var a = ev.target.closest ? ev.target.closest("a") : null;
    var href = a && (a.getAttribute("href") || a.getAttribute("xlink:href"));
    if (href && href.charAt(0) === "#" && href.length > 1) {
      if (("#" + href.slice(1)) === location.hash) reveal(href.slice(1));
    }
  });
  if (location.hash) fromHash();

  function cellValue(row, i, numeric) {
    var td = row.cells[i];
    if (!td) return numeric ? NaN : "";
    var v = td.hasAttribute("data-v") ? td.getAttribute("data-v") : td.textContent;
    if (!numeric) return v.trim().toLowerCase();
    return v === "" ? NaN : parseFloat(v);
  }
  document.querySelectorAll("table.sortable").forEach(function (table) {
    var heads = table.tHead.rows[0].cells;
    Array.prototype.forEach.call(heads, function (th, i) {
      var button = th.querySelector("button");
      if (!button) return;
      button.addEventListener("click", function () {
        var numeric = th.getAttribute("data-type") === "num";
        var dir = th.getAttribute("aria-sort") === "ascending" ? -1 : 1;
        Array.prototype.forEach.call(heads, function (h) { h.removeAttribute("aria-sort"); });
        th.setAttribute("aria-sort", dir === 1 ? "ascending" : "descending");
        var body = table.tBodies[0];
        var rows = Array.prototype.slice.call(body.rows);
        rows.sort(function (a, b) {
          var x = cellValue(a, i, numeric), y = cellValue(b, i, numeric);
          if (numeric) {
            if (isNaN(x) && isNaN(y)) return 0;
            if (isNaN(x)) return 1;  /* missing values last either way */
            if (isNaN(y)) return -1;
            return dir * (x - y);
          }
          return dir * (x < y ? -1 : x > y ? 1 : 0);
        });
        rows.forEach(function (r) { body.appendChild(r); });
      });
    });
  });

  document.querySelectorAll(".filters").forEach(function (box) {
    var table = document.getElementById(box.getAttribute("data-table"));
    var inputs = box.querySelectorAll("[data-filter]");
    var count = box.querySelector("[data-count]");
    function apply() {
      var shown = 0, rows = table.tBodies[0].rows;
      Array.prototype.forEach.call(rows, function (row) {
        var ok = true;
        inputs.forEach(function (input) {
          var want = input.value.trim().toLowerCase();
          if (!want) return;
          var have = (row.getAttribute("data-" + input.getAttribute("data-filter")) || "").toLowerCase();
          if (input.tagName === "SELECT" ? have !== want : have.indexOf(want) < 0) ok = false;
        });
        row.hidden = !ok;
        if (ok) shown += 1;
      });
      if (count) count.textContent = shown + " of " + rows.length + " shown";
    }
    inputs.forEach(function (input) { input.addEventListener("input", apply); });
    apply();
  });
})();
