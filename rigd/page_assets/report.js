// The interactive compare / diagnose page of rigd (rigd/htmlpage.py inlines this script,
// plotly.min.js and the page data). Everything shown is in the page data: no request is made,
// so the page works from a file URL and when `rigd web` serves the folder.
(function () {
  "use strict";
  var D = JSON.parse(document.getElementById("page-data").textContent);
  var app = document.getElementById("app");
  var CFG = {responsive: true, displaylogo: false};
  var C = {meas: "#222", base: "#999", cur: "#1f77b4", res: "#d62728",
    resid: ["#d62728", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#2ca02c"]};

  function el(tag, attrs, children) {
    var e = document.createElement(tag);
    Object.keys(attrs || {}).forEach(function (k) {
      if (k === "text") e.textContent = attrs[k];
      else if (k === "cls") e.className = attrs[k];
      else e.setAttribute(k, attrs[k]);
    });
    (children || []).forEach(function (c) { if (c) e.appendChild(c); });
    return e;
  }
  function fmt(v, d) { return v === null || v === undefined ? "–" : Number(v).toFixed(d); }
  function g(v) { return v === null || v === undefined ? "–" : Number(v).toPrecision(4); }
  function slug(s) { return String(s).replace(/[^A-Za-z0-9_-]/g, "_"); }
  function sameSet(a, b) {
    if (a.length !== b.length) return false;
    return a.every(function (x) { return b.indexOf(x) >= 0; });
  }
  function table(head, rows) {
    return el("table", {}, [el("tr", {}, head.map(function (h) { return el("th", {text: h}); }))]
      .concat(rows.map(function (r) {
        return el("tr", {}, r.map(function (c) {
          return c instanceof Node ? el("td", {}, [c]) : el("td", {text: String(c)});
        }));
      })));
  }

  // --- plots -------------------------------------------------------------------------------
  function timeFigure(P, cur, base) {
    var ny = P.outputs.length, rows = ny + 1, traces = [], layout = {
      margin: {l: 60, r: 10, t: 10, b: 40}, legend: {orientation: "h", y: -0.12},
      xaxis: {title: {text: "time (s)"}, anchor: "y" + (rows === 1 ? "" : rows)}, shapes: []};
    var h = 1 / rows;
    for (var r = 0; r < rows; r++) {
      var name = "yaxis" + (r === 0 ? "" : r + 1);
      layout[name] = {domain: [1 - (r + 1) * h + 0.03, 1 - r * h - 0.01],
        title: {text: r < ny ? P.outputs[r] : "residual"}};
    }
    function ax(r) { return r === 0 ? "y" : "y" + (r + 1); }
    P.outputs.forEach(function (o, i) {
      var m = P.measured.traces[i];
      traces.push({x: m.x, y: m.y, name: "measured " + o, yaxis: ax(i), mode: "lines",
        line: {color: C.meas, width: 1}});
      if (base && base !== cur) traces.push({x: base.traces[i].x, y: base.traces[i].y,
        name: base.label + " " + o, yaxis: ax(i), mode: "lines",
        line: {color: C.base, width: 1, dash: "dot"}});
      traces.push({x: cur.traces[i].x, y: cur.traces[i].y, name: cur.label + " " + o,
        yaxis: ax(i), mode: "lines", line: {color: C.cur, width: 1}});
      if (base && base !== cur) traces.push({x: base.residual[i].x, y: base.residual[i].y,
        name: "residual " + o + ", " + base.label, yaxis: ax(ny), mode: "lines",
        line: {color: C.base, width: 1}});
      traces.push({x: cur.residual[i].x, y: cur.residual[i].y, name: "residual " + o +
        (base && base !== cur ? ", " + cur.label : ""), yaxis: ax(ny), mode: "lines",
        line: {width: 1, color: C.resid[i % C.resid.length]}});
    });
    if (P.val_s) layout.shapes.push({type: "rect", xref: "x", yref: "paper", x0: P.val_s[0],
      x1: P.val_s[1], y0: 0, y1: 1, fillcolor: "#1f77b4", opacity: 0.06, line: {width: 0}});
    (P.marks || []).filter(function (m) { return m.kind === "time"; }).forEach(function (m) {
      layout.shapes.push({type: "rect", xref: "x", yref: "paper", x0: m.t0, x1: m.t1, y0: 0,
        y1: 1, fillcolor: "#ff7f0e", opacity: 0.12, line: {width: 0}});
      traces.push({x: [m.t0], y: [null], name: "unexplained: " + m.text, mode: "markers",
        marker: {color: "#ff7f0e", symbol: "square", size: 10}, yaxis: "y"});
    });
    return {data: traces, layout: layout};
  }

  function spectrumFigure(P, cur, base) {
    var data = [{x: P.measured.spectrum.f, y: P.measured.spectrum.p, name: "measured output",
      mode: "lines", line: {color: C.meas, width: 1}}];
    if (base && base !== cur) data.push({x: base.spectrum.f, y: base.spectrum.p,
      name: "residual, " + base.label, mode: "lines", line: {color: C.base, width: 1}});
    data.push({x: cur.spectrum.f, y: cur.spectrum.p, name: "residual, " + cur.label,
      mode: "lines", line: {color: C.res, width: 1}});
    // the model's peaks as traces (a shape or annotation on a log axis wants log10 coordinates)
    var lo = Infinity, hi = 0;
    data.forEach(function (d) { d.y.forEach(function (v) {
      if (v > 0) { lo = Math.min(lo, v); hi = Math.max(hi, v); } }); });
    if (!(hi > 0 && isFinite(lo))) { lo = 1e-12; hi = 1; }    // all zero: any span
    P.peaks_hz.forEach(function (f, i) {
      data.push({x: [f, f], y: [lo, hi], mode: "lines+text", text: ["", g(f) + " Hz"],
        textposition: i % 2 ? "bottom center" : "top center", textfont: {size: 10},
        name: P.peaks_label, legendgroup: "res", showlegend: i === 0,
        line: {dash: "dash", width: 1, color: "#444"}, hoverinfo: "x"});
    });
    // bands where unexplained structure lies, as filled traces (data coordinates)
    (P.marks || []).filter(function (m) { return m.kind === "band"; }).forEach(function (m, i) {
      data.push({x: [m.lo, m.hi, m.hi, m.lo, m.lo], y: [lo, lo, hi, hi, lo], fill: "toself",
        mode: "lines", line: {width: 0}, fillcolor: "rgba(255,127,14,0.15)",
        name: "unexplained band", legendgroup: "unexpl", showlegend: i === 0,
        hoverinfo: "text", text: m.text});
    });
    return {data: data, layout: {margin: {l: 60, r: 10, t: 24, b: 40},
      xaxis: {type: "log", title: {text: "frequency (Hz)"}},
      yaxis: {type: "log", title: {text: "PSD"}}, legend: {orientation: "h", y: -0.25},
      title: {text: "residual spectrum; dashed: " + P.peaks_label, font: {size: 13}}}};
  }

  function amplitudeFigure(P, cur, base) {
    var data = [];
    if (base && base !== cur) data.push({x: base.amplitude.centre, y: base.amplitude.rms,
      name: base.label, mode: "lines+markers", line: {color: C.base}});
    data.push({x: cur.amplitude.centre, y: cur.amplitude.rms, name: cur.label,
      mode: "lines+markers", line: {color: C.cur}});
    return {data: data, layout: {margin: {l: 60, r: 10, t: 24, b: 40},
      title: {text: "residual RMS by amplitude", font: {size: 13}},
      xaxis: {title: {text: "|measured − mean| (max over outputs)"}},
      yaxis: {title: {text: "residual RMS"}, rangemode: "tozero"},
      legend: {orientation: "h", y: -0.25}}};
  }

  function polarFigure(P, cur, base) {
    var data = [];
    function add(v, dash) {
      P.outputs.forEach(function (o, i) {
        data.push({type: "scatterpolar", theta: v.angle.deg.concat([v.angle.deg[0]]),
          r: v.angle.mean[i].concat([v.angle.mean[i][0]]), mode: "lines",
          name: o + ", " + v.label, line: {dash: dash}});
      });
    }
    if (base && base !== cur) add(base, "dot");
    add(cur, "solid");
    return {data: data, layout: {margin: {l: 30, r: 30, t: 30, b: 30},
      title: {text: "mean residual by shaft angle φ", font: {size: 13}},
      legend: {orientation: "h"}}};
  }

  // --- a part (one sub-model) --------------------------------------------------------------
  function Part(P, root) {
    var id = slug(P.name), self = this;
    this.P = P;
    this.base = P.variants[0];
    this.cur = P.variants[P.steps ? P.steps[P.steps.length - 1].variant : 0];
    root.appendChild(el("h2", {text: P.name + " sub-model"}));
    if (D.kind === "diagnose") {
      this.fit = el("span", {cls: "fit", id: "fit-" + id});
      this.err = el("span", {cls: "err", id: "err-" + id});
      this.label = el("span", {id: "label-" + id});
      root.appendChild(el("p", {cls: "fitline"}, [document.createTextNode("Shown: "),
        this.label, document.createTextNode(" — validation fit "), this.fit,
        document.createTextNode(", error (100 − fit) "), this.err]));
      var boxes = el("fieldset", {cls: "toggles"}, [el("legend", {text:
        "effects tested by diagnose (switch on/off)"})]);
      this.boxes = [];
      P.effects.filter(function (e) { return e.toggle; }).forEach(function (e) {
        var cb = el("input", {type: "checkbox", id: "toggle-" + id + "-" + slug(e.name),
          "data-effect": e.name});
        cb.checked = self.cur.effects.indexOf(e.name) >= 0;
        cb.addEventListener("change", function () { self.onToggle(); });
        self.boxes.push(cb);
        boxes.appendChild(el("label", {cls: e.significant ? "sig" : ""}, [cb,
          document.createTextNode(" " + e.effect + (e.site ? " (" + e.site + ")" : "") +
            (e.significant ? " (significant, step " +
            e.step + ")" : ""))]));
      });
      if (!this.boxes.length) boxes.appendChild(el("span", {text: "none: no tested effect " +
        "was refitted (no signature in the residual, or the record cannot reveal it)"}));
      this.msg = el("div", {cls: "msg", id: "msg-" + id});
      boxes.appendChild(this.msg);
      root.appendChild(boxes);
      root.appendChild(el("h3", {text: "Watch the error fall (forward selection)"}));
      this.stepRows = P.steps.map(function (s, i) {
        var tr = el("tr", {cls: "step", "data-variant": s.variant}, [
          el("td", {text: String(i)}), el("td", {text: s.added === null ? "base model" :
            "+ " + s.added}), el("td", {text: fmt(s.fit_before, 2)}),
          el("td", {text: fmt(s.fit_percent, 2)}),
          el("td", {text: (s.error_before === null ? "" : fmt(s.error_before, 2) + " → ") +
            fmt(s.error_percent, 2)}),
          el("td", {text: s.error_before === null ? "" :
            (s.error_before / Math.max(s.error_percent, 1e-12)).toFixed(2) + "×"})]);
        tr.addEventListener("click", function () { self.show(P.variants[s.variant], true); });
        return tr;
      });
      root.appendChild(el("table", {id: "steps-" + id}, [el("tr", {}, ["step", "model",
        "fit before %", "fit after %", "error before → after", "error ÷"].map(function (h) {
        return el("th", {text: h}); }))].concat(this.stepRows)));
      root.appendChild(el("h3", {text: "Findings and their evidence"}));
      root.appendChild(table(["effect", "significant", "score", "signature", "fit with it %",
        "explanation", "evidence"], P.effects.map(function (e) {
        var ev = el("details", {cls: "evidence"}, [el("summary", {text: "numbers"})].concat(
          Object.keys(e.evidence).map(function (k) {
            return el("div", {text: k + ": " + JSON.stringify(e.evidence[k])}); })));
        return [e.effect + (e.site ? " (" + e.site + ")" : ""), e.significant ? "yes" : "no",
          fmt(e.score, 3), fmt(e.signature_score, 3), fmt(e.fit_percent_with, 2),
          e.explanation, ev];
      })));
      P.cannot_reveal.forEach(function (c) {
        root.appendChild(el("p", {text: "Cannot tell " + c.effect + ": " + c.why +
          ". Experiment: " + c.experiment + "."}));
      });
      P.unexplained.forEach(function (u) {
        root.appendChild(el("p", {cls: "msg", text: "Unexplained: " + u.text + "."}));
      });
    } else {
      root.appendChild(table(["output", "fit %", "residual rms", "residual mean",
        "lag-1 autocorr"], P.table.map(function (r) {
        return [r.output, fmt(r.fit_percent, 2), g(r.rms), g(r.mean), fmt(r.autocorr_lag1, 3)];
      })));
    }
    this.divs = {time: el("div", {cls: "plot tall", id: "time-" + id}),
      spectrum: el("div", {cls: "plot", id: "spectrum-" + id}),
      amplitude: el("div", {cls: "plot", id: "amplitude-" + id})};
    root.appendChild(el("h3", {text: "Measured vs model (drag to zoom, double-click to " +
      "reset" + (P.val_s ? "; shaded: validation part" : "") + ")"}));
    root.appendChild(this.divs.time);
    var row = el("div", {cls: "row"}, [this.divs.spectrum, this.divs.amplitude]);
    if (this.base.angle) {
      this.divs.polar = el("div", {cls: "plot", id: "polar-" + id});
      row.appendChild(this.divs.polar);
    }
    root.appendChild(row);
    this.show(this.cur, false);
  }

  Part.prototype.onToggle = function () {
    var want = this.boxes.filter(function (b) { return b.checked; })
      .map(function (b) { return b.getAttribute("data-effect"); });
    var v = this.P.variants.filter(function (x) { return sameSet(x.effects, want); })[0];
    if (!v) {
      this.msg.textContent = "diagnose did not fit this combination (" +
        (want.join(" + ") || "none") + "); fitted: " + this.P.variants.map(function (x) {
          return x.effects.join(" + ") || "base"; }).join("; ");
      return;
    }
    this.show(v, false);
  };

  Part.prototype.show = function (v, setBoxes) {
    var P = this.P, base = this.base;
    this.cur = v;
    if (this.fit) {
      this.msg.textContent = "";
      this.fit.textContent = fmt(v.fit_percent, 2) + " %";
      this.fit.setAttribute("data-fit", v.fit_percent);
      this.err.textContent = fmt(v.error_percent, 2) + (v === base ? "" : " (base " +
        fmt(base.error_percent, 2) + ")");
      this.label.textContent = v.label;
      if (setBoxes) this.boxes.forEach(function (b) {
        b.checked = v.effects.indexOf(b.getAttribute("data-effect")) >= 0; });
      this.stepRows.forEach(function (tr) {
        tr.classList.toggle("current", P.variants[+tr.getAttribute("data-variant")] === v);
      });
    }
    var figs = {time: timeFigure(P, v, base), spectrum: spectrumFigure(P, v, base),
      amplitude: amplitudeFigure(P, v, base)};
    if (this.divs.polar) figs.polar = polarFigure(P, v, base);
    var divs = this.divs;
    Object.keys(figs).forEach(function (k) {
      var keep = divs[k].layout && divs[k].layout.xaxis && k === "time" ?
        divs[k].layout.xaxis.range : null;     // a zoom survives switching models
      if (keep && divs[k].layout.xaxis.autorange === false) {
        figs[k].layout.xaxis.range = keep.slice();
        figs[k].layout.xaxis.autorange = false;
      }
      Plotly.react(divs[k], figs[k].data, figs[k].layout, CFG);
    });
  };

  // --- page ----------------------------------------------------------------------------------
  if (D.notes && D.notes.length) app.appendChild(el("ul", {cls: "notes"},
    D.notes.map(function (n) { return el("li", {text: n}); })));
  window.rigdReport = {parts: {}};
  D.parts.forEach(function (P) {
    var sec = el("section", {id: "part-" + slug(P.name)});
    app.appendChild(sec);
    window.rigdReport.parts[P.name] = new Part(P, sec);
  });
  if (D.figures && D.figures.length) {
    app.appendChild(el("h2", {text: "Figures (PNG, for papers)"}));
    app.appendChild(el("p", {}, [el("a", {href: "figures.html", text:
      "the figures with their captions"})]));
    app.appendChild(el("details", {id: "figures"}, [el("summary", {text:
      "show the PNG figures"})].concat(
      D.figures.map(function (f) {
        return el("figure", {}, [el("img", {src: f, alt: f, loading: "lazy"}),
          el("figcaption", {text: f})]);
      }))));
  }
  document.body.setAttribute("data-ready", "1");
})();
