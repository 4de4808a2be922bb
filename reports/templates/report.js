/* raster-oracle report: sortable tables, A/B + wipe viewers, worst-tile highlights.
   Reads its data from the <script type="application/json" id="report-data"> block only. */
(function () {
  "use strict";

  var data = JSON.parse(document.getElementById("report-data").textContent);

  /* ---- sortable tables ------------------------------------------------------------ */

  function sortValue(row, col, numeric) {
    var cell = row.cells[col];
    if (!numeric) return cell.textContent.trim().toLowerCase();
    var raw = cell.getAttribute("data-sort");
    return raw === null || raw === "" ? NaN : Number(raw);
  }

  function compareNumbers(a, b) {
    var na = Number.isNaN(a), nb = Number.isNaN(b);
    if (na || nb) return na === nb ? 0 : (na ? 1 : -1);
    return a < b ? -1 : (a > b ? 1 : 0);
  }

  function sortTable(table, th, col) {
    var numeric = th.getAttribute("data-type") === "number";
    var ascending = th.getAttribute("aria-sort") !== "ascending";
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (other) {
      if (other.hasAttribute("aria-sort")) other.setAttribute("aria-sort", "none");
    });
    th.setAttribute("aria-sort", ascending ? "ascending" : "descending");
    var body = table.tBodies[0];
    var rows = Array.prototype.slice.call(body.rows);
    var keyed = rows.map(function (row, index) {
      return { row: row, key: sortValue(row, col, numeric), index: index };
    });
    keyed.sort(function (a, b) {
      var c;
      if (numeric) {
        var missing = Number.isNaN(a.key) - Number.isNaN(b.key);
        if (missing) return missing; /* missing values last in both directions */
        c = compareNumbers(a.key, b.key);
      } else {
        c = a.key.localeCompare(b.key, undefined, { numeric: true });
      }
      return (ascending ? c : -c) || a.index - b.index;
    });
    keyed.forEach(function (item) { body.appendChild(item.row); });
  }

  document.querySelectorAll("table.sortable").forEach(function (table) {
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, col) {
      var button = th.querySelector("button");
      if (button) button.addEventListener("click", function () { sortTable(table, th, col); });
    });
  });

  /* ---- A/B + wipe viewers --------------------------------------------------------- */

  var viewers = [];

  function setupViewer(section) {
    var viewer = section.querySelector(".viewer");
    var reference = section.querySelector('img[data-image="reference"]');
    var candidate = section.querySelector('img[data-image="candidate"]');
    if (!viewer || !reference || !candidate) return;
    var base = viewer.querySelector(".layer-base");
    var wipe = viewer.querySelector(".layer-wipe");
    var slider = section.querySelector("input.wipe");
    var button = section.querySelector("button.ab-toggle");
    var refSrc = reference.getAttribute("src");
    var candSrc = candidate.getAttribute("src");
    var state = { pinned: false, held: false };
    wipe.setAttribute("src", refSrc);

    function render() {
      var showReference = state.pinned || state.held;
      var src = showReference ? refSrc : candSrc;
      if (base.getAttribute("src") !== src) base.setAttribute("src", src);
      base.setAttribute("alt", showReference ? "Reference (A/B viewer)" : "Candidate (A/B viewer)");
      viewer.classList.toggle("showing-reference", showReference);
      viewer.setAttribute("data-showing", showReference ? "reference" : "candidate");
      button.setAttribute("aria-pressed", state.pinned ? "true" : "false");
      button.textContent = state.pinned ? "A/B: show candidate" : "A/B: show reference";
    }

    function setWipe(percent) {
      percent = Math.max(0, Math.min(100, percent));
      viewer.style.setProperty("--wipe", percent + "%");
      slider.value = String(Math.round(percent));
    }

    slider.addEventListener("input", function () { setWipe(Number(slider.value)); });
    button.addEventListener("click", function () { state.pinned = !state.pinned; render(); });

    var dragging = false;
    function dragTo(event) {
      var box = viewer.getBoundingClientRect();
      setWipe(100 * (event.clientX - box.left) / box.width);
    }
    viewer.addEventListener("pointerdown", function (event) {
      if (event.target.classList.contains("tile-box")) return;
      dragging = true;
      viewer.setPointerCapture(event.pointerId);
      dragTo(event);
    });
    viewer.addEventListener("pointermove", function (event) { if (dragging) dragTo(event); });
    viewer.addEventListener("pointerup", function () { dragging = false; });
    viewer.addEventListener("pointercancel", function () { dragging = false; });

    setWipe(Number(slider.value));
    render();
    viewers.push({ state: state, render: render });
  }

  document.querySelectorAll("section.case").forEach(setupViewer);

  function isControl(target) {
    var tag = target && target.tagName;
    return tag === "INPUT" || tag === "TEXTAREA" || tag === "SELECT" || tag === "BUTTON" ||
      (target && target.isContentEditable);
  }

  function holdAll(held) {
    viewers.forEach(function (v) {
      if (v.state.held !== held) { v.state.held = held; v.render(); }
    });
  }

  document.addEventListener("keydown", function (event) {
    if (event.code !== "Space" || isControl(event.target)) return;
    event.preventDefault();
    if (!event.repeat) holdAll(true);
  });
  document.addEventListener("keyup", function (event) {
    if (event.code === "Space") holdAll(false);
  });
  window.addEventListener("blur", function () { holdAll(false); });

  /* ---- worst tiles and synchronized cursor ------------------------------------------ */

  function pct(value, total) { return (100 * value / total) + "%"; }

  function highlight(section, index, on) {
    section.querySelectorAll('[data-tile="' + index + '"]').forEach(function (el) {
      el.classList.toggle("hot", on);
    });
  }

  data.cases.forEach(function (info) {
    var section = document.getElementById(info.id);
    if (!section) return;
    var frames = section.querySelectorAll(".frame");
    var cursors = [];

    frames.forEach(function (frame) {
      info.tiles.forEach(function (tile, index) {
        var box = document.createElement("div");
        box.className = "tile-box";
        box.setAttribute("data-tile", String(index));
        box.style.left = pct(tile.x, info.width);
        box.style.top = pct(tile.y, info.height);
        box.style.width = pct(tile.w, info.width);
        box.style.height = pct(tile.h, info.height);
        box.title = "Worst tile #" + tile.rank + ": x " + tile.x + "–" + (tile.x + tile.w) +
          ", y " + tile.y + "–" + (tile.y + tile.h);
        var label = document.createElement("span");
        label.textContent = String(tile.rank);
        box.appendChild(label);
        box.addEventListener("mouseenter", function () { highlight(section, index, true); });
        box.addEventListener("mouseleave", function () { highlight(section, index, false); });
        box.addEventListener("click", function (event) {
          event.stopPropagation();
          var card = section.querySelector('.tile-card[data-tile="' + index + '"]');
          if (card) {
            card.scrollIntoView({ block: "nearest", behavior: "smooth" });
            card.focus({ preventScroll: true });
          }
        });
        frame.appendChild(box);
      });
      var cursor = document.createElement("div");
      cursor.className = "cursor-box";
      frame.appendChild(cursor);
      cursors.push(cursor);
    });

    /* One cursor square (one tile in size) follows the mouse in every image of the case. */
    var tileSize = info.tiles.length ? info.tiles[0].w : 32;
    frames.forEach(function (frame) {
      frame.addEventListener("mousemove", function (event) {
        var box = frame.getBoundingClientRect();
        var fx = (event.clientX - box.left) / box.width;
        var fy = (event.clientY - box.top) / box.height;
        cursors.forEach(function (c) {
          c.style.display = "block";
          c.style.width = pct(tileSize, info.width);
          c.style.height = pct(tileSize, info.height);
          c.style.left = "calc(" + (100 * fx) + "% - " + (50 * tileSize / info.width) + "%)";
          c.style.top = "calc(" + (100 * fy) + "% - " + (50 * tileSize / info.height) + "%)";
        });
      });
      frame.addEventListener("mouseleave", function () {
        cursors.forEach(function (c) { c.style.display = "none"; });
      });
    });

    section.querySelectorAll(".tile-card").forEach(function (card) {
      var index = card.getAttribute("data-tile");
      card.addEventListener("mouseenter", function () { highlight(section, index, true); });
      card.addEventListener("mouseleave", function () { highlight(section, index, false); });
      card.addEventListener("focus", function () { highlight(section, index, true); });
      card.addEventListener("blur", function () { highlight(section, index, false); });
    });
  });
})();
