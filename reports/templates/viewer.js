/* raster-oracle pixel viewer: nearest-neighbour zoom and pan, exposure, pixel readout, A/B
   and wipe, synced over the reference, candidate, error and wipe views of one case.
   Data: the "viewer" record of each case in the report-data block (reports/viewer.py):
   float16 arrays, byte-shuffled (low bytes, then high bytes), zlib-compressed, base64. The display transform is the one of
   metrics/tonemap.py: clamp at 0, scale by 2^exposure, curve (aces | reinhard | clip), clip to
   [0, 1], sRGB encode (colour only), round to 8 bits. */
(function () {
  "use strict";

  var data = JSON.parse(document.getElementById("report-data").textContent);
  var MAX_PIXEL_CSS = 64; /* deepest zoom: one image pixel = 64 CSS pixels */
  var STEP = 1.25;        /* zoom factor per wheel notch */
  var viewers = [];

  /* ---- decoding ------------------------------------------------------------------ */

  var HALF = (function () {
    var table = new Float32Array(65536);
    for (var h = 0; h < 65536; h++) {
      var sign = h & 0x8000 ? -1 : 1, e = (h >> 10) & 0x1f, f = h & 0x3ff;
      if (e === 0) table[h] = sign * Math.pow(2, -14) * (f / 1024);
      else if (e === 31) table[h] = f ? NaN : sign * Infinity;
      else table[h] = sign * Math.pow(2, e - 15) * (1 + f / 1024);
    }
    return table;
  })();

  function inflate(text) {
    var binary = atob(text);
    var bytes = new Uint8Array(binary.length);
    for (var i = 0; i < binary.length; i++) bytes[i] = binary.charCodeAt(i);
    var stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Response(stream).arrayBuffer().then(function (buffer) {
      /* byte-shuffled: the n low bytes, then the n high bytes */
      var bytes = new Uint8Array(buffer), n = bytes.length >> 1;
      var out = new Float32Array(n);
      for (var k = 0; k < n; k++) out[k] = HALF[bytes[k] | (bytes[n + k] << 8)];
      return out;
    });
  }

  /* ---- display transform (metrics/tonemap.py) -------------------------------------- */

  function srgb(x) { return x <= 0.0031308 ? 12.92 * x : 1.055 * Math.pow(x, 1 / 2.4) - 0.055; }
  function aces(x) { return (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14); }
  function clip01(x) { return x < 0 ? 0 : (x > 1 ? 1 : x); }

  function toneImage(values, v, exposure) {
    var n = v.width * v.height, c = v.channels, scale = Math.pow(2, exposure);
    var out = new ImageData(v.width, v.height), px = out.data;
    var rgb = [0, 0, 0];
    for (var i = 0; i < n; i++) {
      for (var k = 0; k < 3; k++) {
        var x = values[i * c + (c === 3 ? k : 0)];
        x = Math.min(Math.max(x, 0) * scale, 1e30);
        rgb[k] = x;
      }
      var y = c === 3 ? 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2] : rgb[0];
      for (k = 0; k < 3; k++) {
        var m = rgb[k];
        if (v.tone_mapper === "aces") m = aces(m);
        else if (v.tone_mapper === "reinhard") m = m / (1 + y);
        m = clip01(m);
        px[4 * i + k] = Math.round((v.srgb ? srgb(m) : m) * 255);
      }
      px[4 * i + 3] = 255;
    }
    return out;
  }

  function errorImage(values, v, lut) {
    var n = v.width * v.height, lo = v.error.range[0], hi = v.error.range[1];
    var entries = lut.length / 3;
    var out = new ImageData(v.width, v.height), px = out.data;
    for (var i = 0; i < n; i++) {
      var t = clip01((values[i] - lo) / (hi - lo));
      var j = 3 * Math.round((t === t ? t : 0) * (entries - 1));
      px[4 * i] = lut[j]; px[4 * i + 1] = lut[j + 1]; px[4 * i + 2] = lut[j + 2]; px[4 * i + 3] = 255;
    }
    return out;
  }

  function bitmap(imageData) {
    var canvas = document.createElement("canvas");
    canvas.width = imageData.width;
    canvas.height = imageData.height;
    canvas.getContext("2d").putImageData(imageData, 0, 0);
    return canvas;
  }

  function fmt(value) {
    if (value === undefined || value === null) return "—";
    if (Number.isNaN(value)) return "nan";
    if (!Number.isFinite(value)) return value > 0 ? "inf" : "-inf";
    if (value === 0) return "0";
    var text = Math.abs(value) < 1e-4 || Math.abs(value) >= 1e6 ?
      value.toExponential(3).replace(/\.?0+e/, "e") : value.toPrecision(4);
    return text.indexOf("e") < 0 && text.indexOf(".") >= 0 ? text.replace(/\.?0+$/, "") : text;
  }

  /* ---- one viewer ----------------------------------------------------------------- */

  function Viewer(root, record, section, tiles) {
    this.root = root;
    this.tiles = tiles || [];
    this.hotTile = -1;
    this.v = record;
    this.section = section;
    this.zoom = 1;
    this.cx = record.width / 2;
    this.cy = record.height / 2;
    this.exposure = Number(record.exposure);
    this.frame = 0;
    this.pinned = false;
    this.held = false;
    this.wipe = 0.5;
    this.cursor = null;
    this.cache = {};
    this.images = null;
    this.values = null;
    var bytes = atob(record.palette);
    this.lut = new Uint8Array(bytes.length);
    for (var i = 0; i < bytes.length; i++) this.lut[i] = bytes.charCodeAt(i);
    this.drawColorbar(root.querySelector(".pv-colorbar canvas"));
    this.panes = Array.prototype.map.call(root.querySelectorAll(".pv-pane"), function (pane) {
      return { el: pane, canvas: pane.querySelector(".pv-canvas-box canvas"), source: pane.getAttribute("data-source") };
    });
    this.showTiles = false;
    this.bind();
    this.load(0);
  }

  /* The error palette, low end left (the palette has 255 or 256 entries: 256 columns). */
  Viewer.prototype.drawColorbar = function (canvas) {
    if (!canvas) return;
    var entries = this.lut.length / 3, image = new ImageData(256, 1);
    for (var i = 0; i < 256; i++) {
      var j = 3 * Math.round(i * (entries - 1) / 255);
      image.data[4 * i] = this.lut[j];
      image.data[4 * i + 1] = this.lut[j + 1];
      image.data[4 * i + 2] = this.lut[j + 2];
      image.data[4 * i + 3] = 255;
    }
    canvas.getContext("2d").putImageData(image, 0, 0);
  };

  Viewer.prototype.load = function (index) {
    var self = this, v = this.v, frame = v.frames[index];
    var pending = this.cache[index];
    if (!pending) {
      var keys = ["reference", "candidate", "stderr", "error"];
      pending = Promise.all(keys.map(function (key) {
        return frame[key] ? inflate(frame[key]) : Promise.resolve(null);
      })).then(function (arrays) {
        return { reference: arrays[0], candidate: arrays[1], stderr: arrays[2], error: arrays[3] };
      });
      this.cache[index] = pending;
    }
    return pending.then(function (values) {
      if (self.frame !== index) return;
      self.values = values;
      self.errorBitmap = bitmap(errorImage(values.error, v, self.lut));
      self.retone();
      self.showFrameMetrics();
      self.root.setAttribute("data-ready", "1");
    }).catch(function (err) {
      self.root.setAttribute("data-ready", "error");
      self.root.querySelector(".pv-note").textContent = "The viewer could not decode its data: " + err;
    });
  };

  Viewer.prototype.retone = function () {
    if (!this.values) return;
    this.images = {
      reference: bitmap(toneImage(this.values.reference, this.v, this.exposure)),
      candidate: bitmap(toneImage(this.values.candidate, this.v, this.exposure)),
      error: this.errorBitmap
    };
    this.draw();
  };

  /* Canvas pixels per image pixel, and the translation, for a canvas of width cw. */
  Viewer.prototype.transform = function (canvas) {
    var s = (canvas.width / this.v.width) * this.zoom;
    return { s: s, tx: canvas.width / 2 - this.cx * s, ty: canvas.height / 2 - this.cy * s };
  };

  Viewer.prototype.sizeCanvas = function (pane) {
    var box = pane.canvas.parentNode.getBoundingClientRect();
    var dpr = window.devicePixelRatio || 1;
    var w = Math.max(1, Math.round(box.width * dpr)), h = Math.max(1, Math.round(box.height * dpr));
    if (pane.canvas.width !== w || pane.canvas.height !== h) {
      pane.canvas.width = w;
      pane.canvas.height = h;
    }
  };

  Viewer.prototype.draw = function () {
    var self = this;
    if (!this.images) return;
    var showReference = this.pinned || this.held;
    this.panes.forEach(function (pane) {
      self.sizeCanvas(pane);
      var canvas = pane.canvas, ctx = canvas.getContext("2d"), t = self.transform(canvas);
      ctx.setTransform(1, 0, 0, 1, 0, 0);
      ctx.fillStyle = "#000";
      ctx.fillRect(0, 0, canvas.width, canvas.height);
      ctx.imageSmoothingEnabled = false;
      var source = pane.source;
      if (source === "compare") source = showReference ? "reference" : "candidate";
      ctx.setTransform(t.s, 0, 0, t.s, t.tx, t.ty);
      ctx.drawImage(self.images[source], 0, 0);
      if (pane.source === "compare" && !showReference) {
        var x = Math.round(self.wipe * canvas.width);
        ctx.save();
        ctx.setTransform(1, 0, 0, 1, 0, 0);
        ctx.beginPath();
        ctx.rect(0, 0, x, canvas.height);
        ctx.clip();
        ctx.setTransform(t.s, 0, 0, t.s, t.tx, t.ty);
        ctx.drawImage(self.images.reference, 0, 0);
        ctx.restore();
        ctx.setTransform(1, 0, 0, 1, 0, 0);
        ctx.fillStyle = "#fff";
        ctx.fillRect(x - 1, 0, 2, canvas.height);
      }
      if (self.showTiles) self.drawTiles(ctx, t);
      if (self.cursor) {
        ctx.setTransform(1, 0, 0, 1, 0, 0);
        var px = t.tx + self.cursor.x * t.s, py = t.ty + self.cursor.y * t.s;
        var size = Math.max(t.s, 6);
        ctx.lineWidth = 1;
        ctx.strokeStyle = "rgba(0,0,0,0.8)";
        ctx.strokeRect(px - (size - t.s) / 2 - 1.5, py - (size - t.s) / 2 - 1.5, size + 3, size + 3);
        ctx.strokeStyle = "#22d3ee";
        ctx.strokeRect(px - (size - t.s) / 2 - 0.5, py - (size - t.s) / 2 - 0.5, size + 1, size + 1);
      }
      pane.el.setAttribute("data-showing", pane.source === "compare" ? source : pane.source);
    });
    var main = this.root.querySelector(".pv-main");
    main.classList.toggle("showing-reference", showReference);
    var ab = this.root.querySelector(".pv-ab");
    ab.setAttribute("aria-pressed", this.pinned ? "true" : "false");
    ab.textContent = this.pinned ? "A/B: show candidate" : "A/B: show reference";
    var label = this.root.querySelector(".pv-zoom-label");
    var cssPerPixel = this.panes[0].canvas.getBoundingClientRect().width / this.v.width * this.zoom;
    label.textContent = this.zoom === 1 ? "fit" : "1 px = " + fmt(cssPerPixel) + " screen px";
    this.root.setAttribute("data-zoom", String(this.zoom));
  };

  /* The worst tiles (full-resolution rectangles) as outlines with their rank. */
  Viewer.prototype.drawTiles = function (ctx, t) {
    var f = this.v.factor, self = this;
    ctx.setTransform(1, 0, 0, 1, 0, 0);
    ctx.font = "600 11px system-ui, sans-serif";
    this.tiles.forEach(function (tile, index) {
      var x = t.tx + tile.x / f * t.s, y = t.ty + tile.y / f * t.s;
      var w = tile.w / f * t.s, h = tile.h / f * t.s;
      var hot = index === self.hotTile;
      ctx.lineWidth = hot ? 3 : 1.5;
      ctx.strokeStyle = "rgba(0,0,0,0.6)";
      ctx.strokeRect(x - 1, y - 1, w + 2, h + 2);
      ctx.strokeStyle = hot ? "#22d3ee" : "#facc15";
      ctx.strokeRect(x, y, w, h);
      ctx.fillStyle = ctx.strokeStyle;
      ctx.fillRect(x + w + 2, y - 1, 14, 14);
      ctx.fillStyle = "#111";
      ctx.fillText(String(tile.rank), x + w + 5, y + 10);
    });
  };

  Viewer.prototype.maxZoom = function () {
    var css = this.panes[0].canvas.getBoundingClientRect().width / this.v.width;
    return Math.max(1, MAX_PIXEL_CSS / Math.max(css, 1e-6));
  };

  /* Zoom by `factor` keeping the image point under canvas point (mx, my) in place. */
  Viewer.prototype.zoomAt = function (factor, canvas, mx, my) {
    var before = this.transform(canvas);
    var ix = (mx - before.tx) / before.s, iy = (my - before.ty) / before.s;
    this.zoom = Math.min(this.maxZoom(), Math.max(1, this.zoom * factor));
    var s = (canvas.width / this.v.width) * this.zoom;
    this.cx = ix - (mx - canvas.width / 2) / s;
    this.cy = iy - (my - canvas.height / 2) / s;
    this.clampCentre();
    this.draw();
  };

  Viewer.prototype.clampCentre = function () {
    var halfW = this.v.width / (2 * this.zoom), halfH = this.v.height / (2 * this.zoom);
    this.cx = Math.min(this.v.width - halfW, Math.max(halfW, this.cx));
    this.cy = Math.min(this.v.height - halfH, Math.max(halfH, this.cy));
  };

  /* Show the full-resolution rectangle (x, y, w, h) as large as fits. */
  Viewer.prototype.zoomTo = function (x, y, w, h) {
    var f = this.v.factor;
    this.zoom = Math.min(this.maxZoom(), Math.max(1, Math.min(this.v.full_width / w, this.v.full_height / h) * 0.8));
    this.cx = (x + w / 2) / f;
    this.cy = (y + h / 2) / f;
    this.clampCentre();
    this.draw();
  };

  Viewer.prototype.canvasPoint = function (canvas, event) {
    var box = canvas.getBoundingClientRect();
    return { x: (event.clientX - box.left) * canvas.width / box.width,
             y: (event.clientY - box.top) * canvas.height / box.height };
  };

  Viewer.prototype.readout = function () {
    var root = this.root, v = this.v, values = this.values, c = this.cursor;
    var cells = root.querySelectorAll(".pv-val");
    if (!c || !values) {
      root.querySelector(".pv-xy").textContent = "—";
      cells.forEach(function (cell) { cell.textContent = "—"; });
      return;
    }
    var f = v.factor, i = c.y * v.width + c.x;
    root.querySelector(".pv-xy").textContent = f === 1 ? "x " + c.x + ", y " + c.y :
      "x " + c.x * f + "–" + Math.min(v.full_width, (c.x + 1) * f) + ", y " + c.y * f + "–" +
      Math.min(v.full_height, (c.y + 1) * f);
    cells.forEach(function (cell) {
      var field = cell.getAttribute("data-field"), arr = values[field];
      if (!arr) { cell.textContent = "—"; return; }
      var n = field === "error" ? 1 : v.channels, parts = [];
      for (var k = 0; k < n; k++) parts.push(fmt(arr[i * n + k]));
      cell.textContent = parts.join(", ");
    });
  };

  Viewer.prototype.showFrameMetrics = function () {
    var box = this.root.querySelector(".pv-frame-metrics");
    if (!box) return;
    var metrics = this.v.frames[this.frame].metrics;
    box.textContent = "";
    var title = document.createElement("strong");
    title.textContent = this.v.frames[this.frame].label + ": ";
    box.appendChild(title);
    if (!metrics) { box.appendChild(document.createTextNode("no per-frame metrics recorded")); return; }
    var parts = [];
    Object.keys(metrics).forEach(function (key) {
      if (metrics[key] !== null && metrics[key] !== undefined) parts.push(key + " " + fmt(Number(metrics[key])));
    });
    box.appendChild(document.createTextNode(parts.join(" · ")));
  };

  Viewer.prototype.bind = function () {
    var self = this, root = this.root;
    root.querySelector(".pv-zoom-in").addEventListener("click", function () {
      var c = self.panes[0].canvas; self.zoomAt(2, c, c.width / 2, c.height / 2);
    });
    root.querySelector(".pv-zoom-out").addEventListener("click", function () {
      var c = self.panes[0].canvas; self.zoomAt(0.5, c, c.width / 2, c.height / 2);
    });
    root.querySelector(".pv-fit").addEventListener("click", function () {
      self.zoom = 1; self.cx = self.v.width / 2; self.cy = self.v.height / 2; self.draw();
    });
    var exposure = root.querySelector(".pv-exposure");
    var exposureOut = root.querySelector(".pv-exposure-value");
    function setExposure(value) {
      self.exposure = value;
      exposure.value = String(value);
      exposureOut.textContent = (value >= 0 ? "+" : "") + value.toFixed(2);
      self.retone();
    }
    exposure.addEventListener("input", function () { setExposure(Number(exposure.value)); });
    root.querySelector(".pv-exposure-reset").addEventListener("click", function () {
      setExposure(Number(exposure.getAttribute("data-default")));
    });
    var frame = root.querySelector(".pv-frame");
    function setFrame(index) {
      self.frame = index;
      frame.value = String(index);
      root.querySelector(".pv-frame-value").textContent = (index + 1) + " / " + self.v.frames.length;
      root.querySelectorAll("tr[data-frame]").forEach(function (row) {
        row.classList.toggle("current", Number(row.getAttribute("data-frame")) === index);
      });
      self.load(index).then(function () { self.readout(); });
    }
    if (frame) {
      frame.addEventListener("input", function () { setFrame(Number(frame.value)); });
      root.querySelectorAll("tr[data-frame] .pv-link").forEach(function (button) {
        button.addEventListener("click", function () {
          setFrame(Number(button.closest("tr").getAttribute("data-frame")));
        });
      });
    }
    root.querySelector(".pv-ab").addEventListener("click", function () {
      self.pinned = !self.pinned; self.draw();
    });
    var wipe = root.querySelector(".pv-wipe");
    wipe.addEventListener("input", function () { self.wipe = Number(wipe.value) / 100; self.draw(); });

    this.panes.forEach(function (pane) {
      var canvas = pane.canvas, drag = null;
      /* keyboard: + / - zoom, 0 fits, arrows pan by a tenth of the view */
      canvas.tabIndex = 0;
      canvas.addEventListener("keydown", function (event) {
        var step = self.v.width / (10 * self.zoom), c = canvas;
        var moves = { ArrowLeft: [-step, 0], ArrowRight: [step, 0], ArrowUp: [0, -step], ArrowDown: [0, step] };
        if (event.key === "+" || event.key === "=") self.zoomAt(2, c, c.width / 2, c.height / 2);
        else if (event.key === "-") self.zoomAt(0.5, c, c.width / 2, c.height / 2);
        else if (event.key === "0") { self.zoom = 1; self.clampCentre(); self.draw(); }
        else if (moves[event.key]) {
          self.cx += moves[event.key][0]; self.cy += moves[event.key][1];
          self.clampCentre(); self.draw();
        } else return;
        event.preventDefault();
      });
      canvas.addEventListener("wheel", function (event) {
        event.preventDefault();
        var p = self.canvasPoint(canvas, event);
        self.zoomAt(event.deltaY < 0 ? STEP : 1 / STEP, canvas, p.x, p.y);
      }, { passive: false });
      canvas.addEventListener("pointerdown", function (event) {
        drag = { x: event.clientX, y: event.clientY, cx: self.cx, cy: self.cy };
        canvas.setPointerCapture(event.pointerId);
      });
      canvas.addEventListener("pointermove", function (event) {
        var p = self.canvasPoint(canvas, event), t = self.transform(canvas);
        if (drag) {
          var scale = canvas.width / canvas.getBoundingClientRect().width / t.s;
          self.cx = drag.cx - (event.clientX - drag.x) * scale;
          self.cy = drag.cy - (event.clientY - drag.y) * scale;
          self.clampCentre();
        }
        var x = Math.floor((p.x - t.tx) / t.s), y = Math.floor((p.y - t.ty) / t.s);
        var inside = x >= 0 && y >= 0 && x < self.v.width && y < self.v.height;
        self.cursor = inside ? { x: x, y: y } : null;
        self.readout();
        self.draw();
      });
      function stop() { drag = null; }
      canvas.addEventListener("pointerup", stop);
      canvas.addEventListener("pointercancel", stop);
      canvas.addEventListener("pointerleave", function () {
        if (drag) return;
        self.cursor = null; self.readout(); self.draw();
      });
    });

    var tilesBox = root.querySelector(".pv-tiles");
    this.showTiles = Boolean(tilesBox && tilesBox.checked && this.tiles.length);
    if (tilesBox) {
      tilesBox.addEventListener("change", function () {
        self.showTiles = tilesBox.checked && self.tiles.length > 0; self.draw();
      });
    }
    if (this.section) {
      this.section.querySelectorAll(".tile-card").forEach(function (card) {
        var index = Number(card.getAttribute("data-tile"));
        card.addEventListener("mouseenter", function () { self.hotTile = index; self.draw(); });
        card.addEventListener("mouseleave", function () { self.hotTile = -1; self.draw(); });
        card.addEventListener("click", function () {
          self.zoomTo(Number(card.getAttribute("data-x")), Number(card.getAttribute("data-y")),
            Number(card.getAttribute("data-w")), Number(card.getAttribute("data-h")));
        });
      });
    }
    if (window.ResizeObserver) {
      new ResizeObserver(function () { self.draw(); }).observe(this.panes[0].canvas.parentNode);
    }
  };

  /* ---- set-up --------------------------------------------------------------------- */

  data.cases.forEach(function (info) {
    if (!info.viewer) return;
    var root = document.querySelector('.pv[data-viewer="' + info.id + '"]');
    if (!root) return;
    viewers.push(new Viewer(root, info.viewer, document.getElementById(info.id), info.tiles));
  });

  function isControl(target) {
    var tag = target && target.tagName;
    return tag === "INPUT" || tag === "TEXTAREA" || tag === "SELECT" || tag === "BUTTON" ||
      (target && target.isContentEditable);
  }
  function holdAll(held) {
    viewers.forEach(function (v) { if (v.held !== held) { v.held = held; v.draw(); } });
  }
  document.addEventListener("keydown", function (event) {
    if (event.code !== "Space" || isControl(event.target)) return;
    if (!event.repeat) holdAll(true);
  });
  document.addEventListener("keyup", function (event) {
    if (event.code === "Space") holdAll(false);
  });
  window.addEventListener("blur", function () { holdAll(false); });
})();
