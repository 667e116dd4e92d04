// DIR/report.html: the page is plain HTML, CSS and JavaScript written here
// (no library), with results.json embedded, so it opens from disk without
// a request; each cell's pass and the reference are float data in
// report_data/*.js (loaded by <script> elements, which browsers allow from
// file://, unlike fetch), so the exposure control scales real radiance.
#include "app/report_html.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include <obscura/error.h>

namespace obscura {
namespace fs = std::filesystem;

std::string base64(const unsigned char* data, size_t n) {
  static const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((n + 2) / 3 * 4);
  for (size_t i = 0; i < n; i += 3) {
    const uint32_t b = uint32_t(data[i]) << 16 | (i + 1 < n ? uint32_t(data[i + 1]) << 8 : 0) | (i + 2 < n ? data[i + 2] : 0);
    out += alphabet[b >> 18 & 63];
    out += alphabet[b >> 12 & 63];
    out += i + 1 < n ? alphabet[b >> 6 & 63] : '=';
    out += i + 2 < n ? alphabet[b & 63] : '=';
  }
  return out;
}

std::string reportImageBase64(const PassImage& img, const PassImage& ref, bool isReference, int factor) {
  const int w = img.width / factor, h = img.height / factor;
  std::vector<unsigned char> bytes(size_t(w) * h * 4 * 4);
  size_t o = 0;
  const auto put = [&](float v) {
    const uint32_t u = std::bit_cast<uint32_t>(v);  // little-endian whatever the host
    for (int k = 0; k < 4; ++k) bytes[o++] = (u >> (8 * k)) & 255;
  };
  const double n = double(factor) * factor;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double sum[4] = {0, 0, 0, 0};
      for (int dy = 0; dy < factor; ++dy)
        for (int dx = 0; dx < factor; ++dx) {
          const size_t i = size_t(y * factor + dy) * img.width + size_t(x * factor + dx);
          for (int c = 0; c < 3; ++c) sum[c] += img.W(c, i);
          sum[3] += ref.a[i] == 1.0f && (isReference || img.a[i] > 0.0f) ? 1.0 : 0.0;
        }
      for (const double v : sum) put(float(v / n));
    }
  return base64(bytes.data(), bytes.size());
}

namespace {

// JSON inside <script>: '<' escaped, so no "</script>" or "<!--" in a
// string can end the element.
std::string scriptJson(const std::string& json) {
  std::string o;
  for (const char c : json) o += c == '<' ? std::string("\\u003c") : std::string(1, c);
  return o;
}


const char* kStyle = R"CSS(
body { font: 14px/1.4 sans-serif; margin: 16px 24px; color: #222; max-width: 1500px; }
h1 { font-size: 20px; margin: 0 0 4px; } h2 { font-size: 16px; margin: 22px 0 6px; }
.note { color: #555; font-size: 12px; }
#plot svg circle.pt { cursor: pointer; }
#plot svg circle.pt.sel { stroke: #000; stroke-width: 2.5; r: 6; }
.views { display: flex; gap: 18px; flex-wrap: wrap; align-items: flex-start; }
.views canvas { image-rendering: pixelated; border: 1px solid #999; }
.controls { display: flex; gap: 14px; align-items: center; flex-wrap: wrap; margin: 6px 0; }
table { border-collapse: collapse; font-size: 12px; }
th, td { border: 1px solid #ccc; padding: 2px 6px; text-align: right; }
th { background: #eee; cursor: pointer; user-select: none; }
td.t, th.t { text-align: left; }
tr.sel td { background: #ffe9a8; }
tbody tr { cursor: pointer; }
.gallery { display: flex; gap: 10px; flex-wrap: wrap; }
.gallery figure { margin: 0; font-size: 11px; }
.gallery img { display: block; border: 1px solid #999; width: 320px; image-rendering: pixelated; }
.gallery.small img { width: 240px; }
#flipview { image-rendering: pixelated; border: 1px solid #999; }
.bar { display: inline-flex; flex-direction: column; align-items: flex-start; font-size: 11px; }
.bar .ticks { display: flex; justify-content: space-between; width: 256px; }
)CSS";

const char* kScript = R"JS(
"use strict";
const R = JSON.parse(document.getElementById("results").textContent);
const META = JSON.parse(document.getElementById("meta").textContent);
const cells = R.cells;
const images = { cells: {}, reference: null };  // decoded Float32Arrays, RGBA per pixel
const state = { selected: 0, exposure: 0, wipe: 0.5, show: "wipe", heat: "e", sortKey: null, sortUp: true };
// The heat maps results.json lists per cell ("...Heatmap": FLIP's, on FLIP's
// own [0, 1] scale), with their names and the cell's mean of each.
const MAPS = { flipHeatmap: { label: "FLIP", mean: "flip" }, flipHdrHeatmap: { label: "HDR-FLIP", mean: "flipHdr" } };
function mapLabel(k) { return MAPS[k] ? MAPS[k].label : k.replace(/Heatmap$/, ""); }
function cellMaps(c) {
  const known = Object.keys(MAPS), rank = function (k) { const i = known.indexOf(k); return i < 0 ? known.length : i; };
  return Object.keys(c).filter(function (k) { return /Heatmap$/.test(k) && typeof c[k] === "string"; })
    .sort(function (a, b) { return rank(a) - rank(b) || a.localeCompare(b); });
}
const anyMaps = cells.some(function (c) { return cellMaps(c).length > 0; });
const ppdText = R.flipPpd ? " at " + fmt(R.flipPpd) + " pixels per degree" : "";

function fmt(v) {
  if (v === undefined || v === null) return "";
  if (typeof v !== "number") return String(v);
  if (v === 0) return "0";
  return String(Number(v.toPrecision(3)));
}
function interval(a) { return a ? "[" + fmt(a[0]) + ", " + fmt(a[1]) + "]" : ""; }
function decode(b64) {
  const bin = atob(b64), view = new DataView(new ArrayBuffer(bin.length));
  for (let i = 0; i < bin.length; ++i) view.setUint8(i, bin.charCodeAt(i));
  const out = new Float32Array(bin.length / 4);
  for (let i = 0; i < out.length; ++i) out[i] = view.getFloat32(4 * i, true);
  return out;
}
// The data scripts call these (report_data/*.js).
window.obscuraReference = function (b64) { images.reference = decode(b64); draw(); };
window.obscuraCell = function (i, b64) { images.cells[i] = decode(b64); draw(); };
function loadScript(src) {
  const s = document.createElement("script");
  s.src = src;
  s.onerror = function () { document.getElementById("status").textContent = "cannot load " + src + " (kept beside report.html)"; };
  document.head.appendChild(s);
}
function cellIndex(config, spp) { return cells.findIndex(function (c) { return c.config === config && c.spp === spp; }); }

function srgb8(v) {
  if (!(v > 0)) return 0;
  const s = v <= 0.0031308 ? 12.92 * v : 1.055 * Math.pow(v, 1 / 2.4) - 0.055;
  return Math.max(0, Math.min(255, Math.round(s * 255)));
}
function heat(x, px, o) {
  x = Math.max(0, Math.min(1, isFinite(x) ? x : 1)) * 5;
  const i = Math.min(Math.floor(x), 4), f = x - i, a = META.stops[i], b = META.stops[i + 1];
  for (let c = 0; c < 3; ++c) px[o + c] = Math.round(a[c] * (1 - f) + b[c] * f);
  px[o + 3] = 255;
}

function draw() {
  const pass = images.cells[state.selected], ref = images.reference;
  const note = document.getElementById("viewnote");
  if (!pass || !ref) { note.textContent = "loading the float data..."; return; }
  const w = META.width, h = META.height, k = Math.pow(2, state.exposure);
  const view = document.getElementById("viewer"), hm = document.getElementById("heat");
  view.width = hm.width = w;
  view.height = hm.height = h;
  // Shown at least ~480 pixels wide (whole-pixel zoom: pixelated, not blurred).
  const zoom = Math.max(1, Math.floor(480 / w));
  view.style.width = hm.style.width = w * zoom + "px";
  const vi = view.getContext("2d").createImageData(w, h), hi = hm.getContext("2d").createImageData(w, h);
  const split = Math.round(state.wipe * w);
  for (let y = 0; y < h; ++y)
    for (let x = 0; x < w; ++x) {
      const p = y * w + x, o = 4 * p;
      const src = state.show === "pass" ? pass : state.show === "reference" ? ref : (x < split ? pass : ref);
      for (let c = 0; c < 3; ++c) vi.data[o + c] = srgb8(src[o + c] * k);
      vi.data[o + 3] = 255;
      if (state.show === "wipe" && x === split) vi.data[o] = vi.data[o + 1] = vi.data[o + 2] = 255;
      if (pass[o + 3] < 0.5) { hi.data[o] = hi.data[o + 1] = hi.data[o + 2] = 64; hi.data[o + 3] = 255; continue; }
      const e = (Math.abs(pass[o] - ref[o]) + Math.abs(pass[o + 1] - ref[o + 1]) + Math.abs(pass[o + 2] - ref[o + 2])) / 3;
      heat(e / META.scale, hi.data, o);
    }
  view.getContext("2d").putImageData(vi, 0, 0);
  hm.getContext("2d").putImageData(hi, 0, 0);
  const c = cells[state.selected];
  // The right-hand view: |e| drawn here, or the cell's FLIP heat map file.
  const fv = document.getElementById("flipview"), heatNote = document.getElementById("heatnote");
  if (state.heat !== "e" && c[state.heat]) {
    fv.src = c[state.heat];
    fv.alt = mapLabel(state.heat) + " of " + c.config + " @ " + c.spp;
    fv.style.width = w * zoom + "px";
    fv.hidden = false;
    hm.hidden = true;
    heatNote.textContent = mapLabel(state.heat) + " per pixel of the first seed's pass" + ppdText +
      ", on FLIP's own scale: 0 (no visible difference) to 1 (grey: not compared); mean " +
      fmt(MAPS[state.heat] ? c[MAPS[state.heat].mean] : undefined);
  } else {
    fv.hidden = true;
    hm.hidden = false;
    heatNote.textContent = "|e| of W, mean over R, G, B, on the shared scale of the colour bar below (grey: not compared)";
  }
  note.textContent = (state.show === "wipe" ? "left of the line: " + c.config + " @ " + c.spp + " spp; right: the GI reference"
    : state.show === "pass" ? c.config + " @ " + c.spp + " spp" : "the GI reference") +
    " (first seed's pass" + (META.factor > 1 ? ", averaged over " + META.factor + "x" + META.factor + " pixels" : "") + ")";
  view.dataset.drawn = "cell-" + state.selected;
}

function select(i) {
  state.selected = i;
  document.querySelectorAll("#plot circle.pt").forEach(function (el) { el.classList.toggle("sel", Number(el.dataset.cell) === i); });
  document.querySelectorAll("#cells tbody tr").forEach(function (tr) { tr.classList.toggle("sel", Number(tr.dataset.cell) === i); });
  const c = cells[i];
  document.getElementById("chosen").textContent = c.config + " @ " + c.spp + " spp: " + fmt(c.seconds) + " s" +
    (c.secondsInterval ? " (runs " + fmt(c.secondsInterval[0]) + " to " + fmt(c.secondsInterval[1]) + " s)" : "") +
    ", RMSE " + fmt(c.rmse) + (c.rmseInterval ? " (95% CI " + fmt(c.rmseInterval[0]) + " to " + fmt(c.rmseInterval[1]) + ")" : "") +
    (c.flip !== undefined ? ", FLIP " + fmt(c.flip) : "") + (c.flipHdr !== undefined ? ", HDR-FLIP " + fmt(c.flipHdr) : "");
  if (images.cells[i]) draw(); else { draw(); loadScript("report_data/cell-" + i + ".js"); }
}

const columns = [
  { key: "config", label: "config", text: true, get: function (c) { return c.config; } },
  { key: "spp", label: "spp", get: function (c) { return c.spp; } },
  { key: "meanSpp", label: "mean spp", get: function (c) { return c.meanSpp; } },
  { key: "seconds", label: "time s", get: function (c) { return c.seconds; } },
  { key: "secondsInterval", label: "time min-max", get: function (c) { return c.secondsInterval ? c.secondsInterval[0] : null; }, show: function (c) { return interval(c.secondsInterval); } },
  { key: "rmse", label: "RMSE", get: function (c) { return c.rmse; } },
  { key: "rmseInterval", label: "RMSE 95% CI", get: function (c) { return c.rmseInterval ? c.rmseInterval[0] : null; }, show: function (c) { return interval(c.rmseInterval); } },
  { key: "relMse", label: "relMSE", get: function (c) { return c.relMse; } },
  { key: "mae", label: "MAE", get: function (c) { return c.mae; } },
  { key: "p99", label: "p99", get: function (c) { return c.p99; } },
  { key: "bias2", label: "bias\u00b2", get: function (c) { return c.bias2; } },
  { key: "variance", label: "variance", get: function (c) { return c.variance; } },
  { key: "flip", label: "FLIP", get: function (c) { return c.flip; } },
  { key: "flipHdr", label: "HDR-FLIP", get: function (c) { return c.flipHdr; } },
  { key: "pareto", label: "Pareto", text: true, get: function (c, i) { return pareto.has(i) ? "yes" : ""; } },
].filter(function (col) { return col.key === "pareto" || cells.some(function (c) { return col.get(c) !== undefined && col.get(c) !== null; }); });
const pareto = new Set((R.paretoFront || []).map(function (p) { return cellIndex(p.config, p.spp); }));

function buildTable() {
  const table = document.getElementById("cells");
  const head = document.createElement("tr");
  columns.forEach(function (col) {
    const th = document.createElement("th");
    th.textContent = col.label + (state.sortKey === col.key ? (state.sortUp ? " \u25b2" : " \u25bc") : "");
    if (col.text) th.className = "t";
    th.addEventListener("click", function () {
      state.sortUp = state.sortKey === col.key ? !state.sortUp : true;
      state.sortKey = col.key;
      buildTable();
    });
    head.appendChild(th);
  });
  const order = cells.map(function (c, i) { return i; });
  if (state.sortKey) {
    const col = columns.find(function (c) { return c.key === state.sortKey; });
    order.sort(function (a, b) {
      const x = col.get(cells[a], a), y = col.get(cells[b], b);
      const r = (x === undefined || x === null) - (y === undefined || y === null) ||
        (col.text ? String(x).localeCompare(String(y)) : x - y);
      return state.sortUp ? r : -r;
    });
  }
  const body = document.createElement("tbody");
  order.forEach(function (i) {
    const c = cells[i], tr = document.createElement("tr");
    tr.dataset.cell = i;
    tr.dataset.config = c.config;
    tr.dataset.spp = c.spp;
    if (i === state.selected) tr.className = "sel";
    columns.forEach(function (col) {
      const td = document.createElement("td");
      td.textContent = col.show ? col.show(c) : col.text ? col.get(c, i) : fmt(col.get(c, i));
      if (col.text) td.className = "t";
      tr.appendChild(td);
    });
    tr.addEventListener("click", function () { select(i); });
    body.appendChild(tr);
  });
  table.replaceChildren(head, body);
}

function buildVerdicts() {
  // One table per measure: targets (RMSE) and flipTargets (FLIP), each row a
  // target with its winner, verdict and confidence.
  const rows = function (list, measure, id) {
    const t = document.getElementById(id);
    list.forEach(function (v) {
      const tr = document.createElement("tr");
      tr.dataset.measure = measure;
      tr.dataset.target = v[measure];
      const f = v.fastest;
      [fmt(v[measure]), f ? f.config + " @ " + f.spp + " spp, " + fmt(f.seconds) + " s" : "not reached", v.verdict || "", v.verdictText || ""]
        .forEach(function (text, k) { const td = document.createElement("td"); td.textContent = text; if (k) td.className = "t"; tr.appendChild(td); });
      if (f) tr.addEventListener("click", function () { select(cellIndex(f.config, f.spp)); });
      t.appendChild(tr);
    });
  };
  rows(R.targets || [], "rmse", "verdicts");
  rows(R.flipTargets || [], "flip", "flipverdicts");
  if (!(R.flipTargets || []).length) document.getElementById("flipverdictsection").hidden = true;
  else document.getElementById("flipverdictnote").textContent = "FLIP" + ppdText + "; the verdict compares the times as for RMSE " +
    "(FLIP itself has no interval: its per-seed values are not kept).";
  const list = document.getElementById("pareto");
  (R.paretoFront || []).forEach(function (p) {
    const li = document.createElement("li"), i = cellIndex(p.config, p.spp);
    li.textContent = p.config + " @ " + p.spp + " spp: " + fmt(cells[i].seconds) + " s, RMSE " + fmt(cells[i].rmse) +
      (cells[i].flip !== undefined ? ", FLIP " + fmt(cells[i].flip) : "");
    li.style.cursor = "pointer";
    li.addEventListener("click", function () { select(i); });
    list.appendChild(li);
  });
}

// A colour bar from 0 to max; `clipped`: larger values are drawn as max.
function buildBar(canvasId, max, clipped) {
  const bar = document.getElementById(canvasId), g = bar.getContext("2d"), img = g.createImageData(256, 12);
  for (let x = 0; x < 256; ++x) for (let y = 0; y < 12; ++y) heat(x / 255, img.data, 4 * (y * 256 + x));
  g.putImageData(img, 0, 0);
  const ticks = bar.parentNode.querySelector(".ticks");
  [0, max / 2, max].forEach(function (v, k) { const s = document.createElement("span"); s.textContent = (k === 2 && clipped ? "\u2265 " : "") + fmt(v); ticks.appendChild(s); });
}

function buildGallery() {
  const g = document.getElementById("gallery"), fg = document.getElementById("flipgallery");
  META.heatmaps.forEach(function (m) {
    const fig = document.createElement("figure"), img = document.createElement("img"), cap = document.createElement("figcaption");
    img.src = m.file;
    img.alt = "|e| of " + m.config + " @ " + m.spp;
    cap.textContent = m.config + " @ " + m.spp + " spp";
    fig.append(img, cap);
    g.appendChild(fig);
  });
  // Heat maps results.json lists per cell (FLIP's: keys ending in "Heatmap"), on FLIP's own 0-1 scale.
  cells.forEach(function (c, i) {
    cellMaps(c).forEach(function (k) {
      const fig = document.createElement("figure"), img = document.createElement("img"), cap = document.createElement("figcaption");
      img.src = c[k];
      img.alt = mapLabel(k) + " of " + c.config + " @ " + c.spp;
      img.dataset.map = k;
      cap.textContent = mapLabel(k) + ": " + c.config + " @ " + c.spp + " spp" +
        (MAPS[k] && c[MAPS[k].mean] !== undefined ? ", mean " + fmt(c[MAPS[k].mean]) : "");
      fig.style.cursor = "pointer";
      fig.addEventListener("click", function () { setHeat(k); select(i); });
      fig.append(img, cap);
      fg.appendChild(fig);
    });
  });
  if (!anyMaps) {
    document.getElementById("flipsection").hidden = true;
    document.querySelectorAll(".mapchoice").forEach(function (el) { el.hidden = true; });
    return;
  }
  document.getElementById("flipnote").textContent = "FLIP per pixel" + ppdText + " (docs/compare.md \"FLIP\"): 0 no " +
    "visible difference, 1 the largest; FLIP's own scale, not |e|'s. Every cell, its first seed's pass; click one to view it above.";
  buildBar("flipbar", 1, false);
}
function setHeat(k) {
  state.heat = k;
  document.querySelectorAll("input[name=heat]").forEach(function (el) { el.checked = el.value === k; });
}

document.querySelectorAll("#plot circle.pt").forEach(function (el) {
  el.addEventListener("click", function () { select(Number(el.dataset.cell)); });
});
document.getElementById("exposure").addEventListener("input", function (e) {
  state.exposure = Number(e.target.value);
  document.getElementById("ev").textContent = (state.exposure > 0 ? "+" : "") + state.exposure.toFixed(1) + " EV";
  draw();
});
document.getElementById("wipe").addEventListener("input", function (e) { state.wipe = Number(e.target.value) / 100; draw(); });
document.querySelectorAll("input[name=show]").forEach(function (el) {
  el.addEventListener("change", function () { state.show = el.value; draw(); });
});
document.querySelectorAll("input[name=heat]").forEach(function (el) {
  el.addEventListener("change", function () { state.heat = el.value; draw(); });
});
document.getElementById("viewer").addEventListener("click", function (e) {
  // A click on the image moves the wipe there.
  const r = e.target.getBoundingClientRect();
  state.wipe = (e.clientX - r.left) / r.width;
  document.getElementById("wipe").value = Math.round(state.wipe * 100);
  draw();
});
buildTable();
buildVerdicts();
buildBar("bar", META.scale, true);
buildGallery();
loadScript("report_data/reference.js");
// The first cell of the Pareto front (the fastest worth looking at), else the first.
if (cells.length) select(Math.min.apply(null, Array.from(pareto).filter(function (i) { return i >= 0; }).concat([cells.length - 1])));
document.body.dataset.status = "ready";
)JS";

}  // namespace

void writeReportHtml(const CompareReport& r, const std::string& resultsJson, const std::string& plotSvg) {
  const fs::path dir(r.dir), dataDir = dir / "report_data";
  std::error_code ec;
  fs::create_directories(dataDir, ec);
  if (ec) throw Error((dataDir).string() + ": cannot create: " + ec.message());
  const PassImage& ref = *r.reference;
  // At most ~640 pixels wide in the page: the float data of a large render
  // would make the folder heavy for no visible gain.
  const int factor = std::max(1, (ref.width + 639) / 640);
  writeTextAtomically(dataDir / "reference.js",
                      "obscuraReference(\"" + reportImageBase64(ref, ref, true, factor) + "\");\n");
  for (size_t i = 0; i < r.cells.size(); ++i) {
    PassImage pass = readPass((dir / r.cells[i].pass).string());
    if (pass.width != ref.width || pass.height != ref.height)
      throw Error((dir / r.cells[i].pass).string() + ": is " + std::to_string(pass.width) + "x" +
                  std::to_string(pass.height) + ", the reference " + std::to_string(ref.width) + "x" +
                  std::to_string(ref.height));
    scaleRgb(pass, r.passScale);
    writeTextAtomically(dataDir / ("cell-" + std::to_string(i) + ".js"),
                        "obscuraCell(" + std::to_string(i) + ", \"" + reportImageBase64(pass, ref, false, factor) + "\");\n");
  }

  const nlohmann::json results = nlohmann::json::parse(resultsJson);
  nlohmann::json meta;
  meta["width"] = ref.width / factor, meta["height"] = ref.height / factor, meta["factor"] = factor;
  meta["scale"] = results.value("heatmapScale", 1.0);
  meta["stops"] = nlohmann::json::array();
  for (const auto& s : kHeatStops) meta["stops"].push_back({s[0], s[1], s[2]});
  meta["heatmaps"] = nlohmann::json::array();
  for (const auto& e : results.value("contactSheet", nlohmann::json::array()))
    if (e.is_object())
      meta["heatmaps"].push_back({{"config", e["config"]}, {"spp", e["spp"]},
                                  {"file", "heatmaps/" + safeFileName(e["config"].get<std::string>()) + ".png"}});

  bool intervals = false;
  for (const ReportCell& c : r.cells) intervals = intervals || c.hasIntervals();
  std::ostringstream h;
  h << "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>obscura compare: "
    << xmlEscape(fs::path(r.scene).filename().string()) << "</title>\n<style>" << kStyle << "</style></head>\n<body>\n"
    << "<h1>Error against full GI vs time: " << xmlEscape(fs::path(r.scene).filename().string()) << "</h1>\n"
    << "<div class=\"note\">camera " << xmlEscape(r.camera) << ", " << xmlEscape(r.resolution) << "; "
    << xmlEscape(r.lighting);
  if (r.referenceNoise >= 0) h << "; reference noise (RMSE of the reference itself) " << r.referenceNoise;
  h << ". Click a point, a row or a verdict to view that cell.</div>\n"
    << "<h2>Error vs time</h2>\n<div id=\"plot\">" << plotSvg << "</div>\n";
  if (intervals)
    h << "<div class=\"note\">Bars: the RMSE's 95% Student-t interval over the seeds (per-seed MSE, ends "
         "square-rooted) and the time's fastest-to-slowest run (docs/compare.md \"Uncertainty\").</div>\n";
  h << "<h2>The chosen cell against the reference</h2>\n<div id=\"chosen\"></div>\n"
    << "<div class=\"controls\"><label>exposure <input id=\"exposure\" type=\"range\" min=\"-8\" max=\"8\" step=\"0.5\" "
       "value=\"0\"></label><span id=\"ev\">0.0 EV</span>"
    << "<label>wipe <input id=\"wipe\" type=\"range\" min=\"0\" max=\"100\" value=\"50\"></label>"
    << "<label><input type=\"radio\" name=\"show\" value=\"wipe\" checked> wipe</label>"
    << "<label><input type=\"radio\" name=\"show\" value=\"pass\"> pass</label>"
    << "<label><input type=\"radio\" name=\"show\" value=\"reference\"> reference</label>"
    << "<span>heat map:</span><label><input type=\"radio\" name=\"heat\" value=\"e\" checked> |e|</label>"
    << "<label class=\"mapchoice\"><input type=\"radio\" name=\"heat\" value=\"flipHeatmap\"> FLIP</label>"
    << "<label class=\"mapchoice\"><input type=\"radio\" name=\"heat\" value=\"flipHdrHeatmap\"> HDR-FLIP</label></div>\n"
    << "<div class=\"views\"><figure style=\"margin:0\"><canvas id=\"viewer\"></canvas><figcaption class=\"note\" "
       "id=\"viewnote\"></figcaption></figure>\n"
    << "<figure style=\"margin:0\"><canvas id=\"heat\"></canvas><img id=\"flipview\" hidden alt=\"\">"
       "<figcaption class=\"note\" id=\"heatnote\">|e| of W, mean over R, G, B (grey: not compared)</figcaption></figure></div>\n"
    << "<div id=\"status\" class=\"note\"></div>\n"
    << "<h2>Heat maps of |e| (each config's highest spp)</h2>\n"
    << "<div class=\"bar\"><canvas id=\"bar\" width=\"256\" height=\"12\"></canvas><div class=\"ticks\"></div>"
       "<span>|e| = |W - W_ref|, one scale for every |e| heat map on this page (results.json heatmapScale)</span></div>\n"
    << "<div id=\"gallery\" class=\"gallery\"></div>\n"
    << "<div id=\"flipsection\"><h2>FLIP and HDR-FLIP heat maps (every cell)</h2>\n"
    << "<div class=\"bar\"><canvas id=\"flipbar\" width=\"256\" height=\"12\"></canvas><div class=\"ticks\"></div>"
       "<span id=\"flipnote\"></span></div>\n"
    << "<div id=\"flipgallery\" class=\"gallery small\"></div></div>\n"
    << "<h2>Verdicts: the fastest config reaching each RMSE target</h2>\n"
    << "<table><thead><tr><th>RMSE target</th><th class=\"t\">fastest</th><th class=\"t\">verdict</th><th "
       "class=\"t\">confidence</th></tr></thead><tbody id=\"verdicts\"></tbody></table>\n"
    << "<div id=\"flipverdictsection\"><h2>Verdicts: the fastest config reaching each FLIP target</h2>\n"
    << "<div class=\"note\" id=\"flipverdictnote\"></div>\n"
    << "<table><thead><tr><th>FLIP target</th><th class=\"t\">fastest</th><th class=\"t\">verdict</th><th "
       "class=\"t\">confidence</th></tr></thead><tbody id=\"flipverdicts\"></tbody></table></div>\n"
    << "<h2>Pareto front (no other cell is both faster and more accurate)</h2>\n<ol id=\"pareto\"></ol>\n"
    << "<h2>Every cell (click a header to sort)</h2>\n<table id=\"cells\"></table>\n"
    << "<script type=\"application/json\" id=\"results\">" << scriptJson(resultsJson) << "</script>\n"
    << "<script type=\"application/json\" id=\"meta\">" << scriptJson(meta.dump()) << "</script>\n"
    << "<script>" << kScript << "</script>\n</body></html>\n";
  writeTextAtomically(dir / "report.html", h.str());
}

}  // namespace obscura
