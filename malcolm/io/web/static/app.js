// The web GUI: a live list of blocks, and a view of the block chosen
// (#/block/<mri>): its state machine, progress, attributes, methods and,
// for a manager, its palette. Everything goes through the public protocol.

import { Palette } from "./canvas.js";
import { Client } from "./client.js";
import { allows, drawModel } from "./fsm.js";
import { attributeRow, h, methodForm, methodKey } from "./widgets.js";

const wsUrl = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
const client = new Client(wsUrl);
const list = document.getElementById("blocks");
const main = document.getElementById("block");
const conn = document.getElementById("connection");
client.onstatus = (s) => { conn.textContent = s; conn.className = s; };

// ---- the block list: state and health, live
const rows = new Map();
// (the server sends the list again whenever a block is added or removed)
client.subscribe([".", "blocks", "value"], (mris) => {
  const served = new Set(mris || []);
  for (const [mri, entry] of rows) {
    if (served.has(mri)) continue;
    for (const sub of entry.subs) client.unsubscribe(sub);
    entry.row.remove();
    rows.delete(mri);
  }
  for (const mri of mris || []) {
    if (rows.has(mri)) continue;
    const state = h("span", { class: "state" });
    const health = h("span", { class: "health" });
    const row = h("li", { "data-mri": mri }, h("a", { href: `#/block/${encodeURIComponent(mri)}` }, mri), state, health);
    list.append(row);
    const subs = [
      client.subscribe([mri, "state", "value"], (v) => { state.textContent = v ?? ""; row.dataset.state = v; }, false),
      client.subscribe([mri, "health", "value"], (v) => {
        health.textContent = v === "OK" ? "" : v ?? "";
        row.classList.toggle("unhealthy", !!v && v !== "OK");
      }, false),
    ];
    rows.set(mri, { row, subs });
  }
  if (!location.hash && mris?.length) location.hash = `#/block/${encodeURIComponent(mris[0])}`;
  else if (!current) route();
}, false);

// ---- the block view
let current = null;

const isAttribute = (d) => /^epics:nt\/NT(Scalar|ScalarArray|Table):1\.0$/.test(d?.typeid || "");
const isMethod = (d) => (d?.typeid || "").startsWith("malcolm:core/Method:");

class BlockView {
  constructor(mri) {
    this.mri = mri;
    this.model = null;
    this.views = new Map();
    this.el = h("div", { class: "blockview", "data-view": mri });
    this.message = h("div", { class: "status error" });
    this.fsm = h("div", { class: "fsmbox" });
    this.sub = client.subscribe([mri], (data, changes, error) => this.changed(data, changes, error));
    client.get([".", "models", mri]).then((model) => {
      this.model = model;
      this.svg = drawModel(model);
      this.fsm.replaceChildren(h("h3", {}, `State machine: ${model.name}`), this.svg);
      if (this.data) this.refresh(this.data, new Set(["state"]));
    }, () => this.fsm.replaceChildren());
  }

  changed(data, changes, error) {
    if (error) { this.el.replaceChildren(h("p", { class: "error" }, error.message)); return; }
    this.data = data;
    if (!data) { this.el.replaceChildren(h("p", {}, "gone")); return; }
    const touched = new Set((changes || [[[]]]).map((c) => c[0][0]));
    if (touched.has(undefined) || touched.has("meta")) this.build(data);
    else this.refresh(data, touched);
  }

  build(data) {
    // views of fields that are still there are kept (with their results)
    const before = this.views;
    this.views = new Map();
    const fields = data.meta?.fields || [];
    this.header = h("div", { class: "header" }, h("h2", {}, this.mri),
      h("span", { class: "badge", "data-block-state": "" }), h("span", { class: "health" }));
    this.progress = null;
    if ("completedSteps" in data && "totalSteps" in data) {
      const bar = h("progress", { "data-progress": this.mri, max: 1, value: 0 });
      const text = h("span", { class: "progress-text" });
      this.progress = { bar, text };
    }
    const attrs = h("section", { class: "attributes" }, h("h3", {}, "Attributes"));
    const methods = h("section", { class: "methods" }, h("h3", {}, "Methods"));
    for (const name of fields) {
      const d = data[name];
      const old = before.get(name);
      if (isAttribute(d)) {
        const view = old?.update ? old : attributeRow(client, this.mri, name, d);
        this.views.set(name, view);
        attrs.append(view.el);
      } else if (isMethod(d)) {
        const view = old?.key === methodKey(d) ? old : methodForm(client, this.mri, name, d);
        this.views.set(name, view);
        methods.append(view.el);
      }
    }
    if ("layout" in data && "exports" in data) {
      this.palette ||= new Palette(client, this.mri, (m) => { this.message.textContent = m; });
    } else {
      this.palette?.close();
      this.palette = null;
    }
    this.el.replaceChildren(
      this.header,
      this.progress ? h("div", { class: "progress" }, this.progress.bar, this.progress.text) : "",
      this.message,
      this.fsm,
      h("div", { class: "columns" },
        h("div", {}, this.palette?.el || "", methods),
        attrs),
    );
    this.refresh(data, new Set(fields));
  }

  refresh(data, touched) {
    const state = data.state?.value;
    this.header.querySelector(".badge").textContent = state ?? "";
    this.header.querySelector(".badge").dataset.blockState = state ?? "";
    const health = data.health?.value;
    const healthEl = this.header.querySelector(".health");
    healthEl.textContent = health ?? "";
    healthEl.classList.toggle("error", !!health && health !== "OK");
    for (const name of touched) {
      const view = this.views.get(name);
      if (view?.update) view.update(data[name]);
    }
    for (const [name, view] of this.views) {
      if (view.enable) {
        const meta = data[name]?.meta;
        view.enable(allows(this.model, name, state) && meta?.writeable !== false);
      }
    }
    if (this.svg && state) this.svg.setState(state);
    if (this.progress && (touched.has("completedSteps") || touched.has("totalSteps"))) {
      const done = data.completedSteps.value, total = data.totalSteps.value;
      this.progress.bar.max = total || 1;
      this.progress.bar.value = done;
      this.progress.text.textContent = `${done} / ${total}`;
      this.progress.bar.dataset.done = done;
      this.progress.bar.dataset.total = total;
    }
    if (this.palette && (touched.has("layout") || touched.has("wiring"))) {
      this.palette.update(data.layout.value, data.wiring?.value);
    }
  }

  close() {
    client.unsubscribe(this.sub);
    this.palette?.close();
  }
}

function route() {
  const m = location.hash.match(/^#\/block\/(.+)$/);
  if (!m) return;
  const mri = decodeURIComponent(m[1]);
  if (current?.mri === mri) return;
  current?.close();
  current = new BlockView(mri);
  main.replaceChildren(current.el);
  for (const [name, { row }] of rows) row.classList.toggle("selected", name === mri);
  document.title = `${mri} · malcolm`;
}

window.addEventListener("hashchange", route);
route();
