// A manager's palette: each visible child drawn at its layout position,
// dragged to move it (set_position), shown or hidden (set_visible); arrows
// where a child's input port (a field tagged sinkPort:/inport:) selects
// another child's output port (tagged sourcePort:/outport:<type>:<name>),
// and for each row of the manager's own `wiring` table (sink, source).

import { h } from "./widgets.js";

const NS = "http://www.w3.org/2000/svg";
const ORIGIN = 20;

function ports(block) {
  const sinks = [], sources = [];
  for (const [field, d] of Object.entries(block || {})) {
    for (const tag of d?.meta?.tags || []) {
      const [what, , name] = tag.split(":");
      if (what === "sinkPort" || what === "inport") sinks.push({ field, source: d.value, none: name });
      if (what === "sourcePort" || what === "outport") sources.push({ field, name });
    }
  }
  return { sinks, sources };
}

export class Palette {
  constructor(client, mri, status) {
    this.client = client;
    this.mri = mri;
    this.status = status;
    this.children = new Map(); // child mri -> {sub, data}
    this.boxes = h("div", { class: "boxes" });
    this.arrows = document.createElementNS(NS, "svg");
    this.arrows.setAttribute("class", "wires");
    this.canvas = h("div", { class: "palette", "data-palette": mri }, this.arrows, this.boxes);
    this.toggles = h("div", { class: "visibility" });
    this.el = h("section", { class: "manager" }, h("h3", {}, "Palette"), this.canvas, this.toggles);
    this.layout = null;
  }

  // `wiring`: a manager's own table of wires (sink, source as BLOCK.FIELD),
  // as a Zebra2 manager has, drawn beside what the children's ports say
  update(layout, wiring) {
    this.layout = layout;
    this.wiring = wiring || this.wiring;
    const rows = (layout.name || []).map((name, i) => ({
      name, mri: layout.mri[i], x: layout.x[i], y: layout.y[i], visible: layout.visible[i],
    }));
    this.rows = rows;
    // boxes are kept (a drag in progress goes on), moved to where they are
    const boxes = new Map([...this.boxes.children].map((el) => [el.dataset.child, el]));
    this.boxes.replaceChildren(...rows.filter((r) => r.visible).map((r) => {
      const el = boxes.get(r.name) || this.box(r);
      if (!el.dragging) {
        el.row = r;
        el.style.left = `${ORIGIN + r.x}px`;
        el.style.top = `${ORIGIN + r.y}px`;
      }
      return el;
    }));
    this.toggles.replaceChildren(...rows.map((r) => h("label", { class: "toggle" },
      h("input", { type: "checkbox", "data-visible": r.name, checked: r.visible, onchange: (e) => this.call("set_visible", { block_name: r.name, visible: e.target.checked }) }),
      r.name)));
    for (const r of rows) {
      if (!this.children.has(r.mri)) {
        const entry = { data: null };
        entry.sub = this.client.subscribe([r.mri], (data) => { entry.data = data; this.wire(); });
        this.children.set(r.mri, entry);
      }
    }
    this.wire();
  }

  box(r) {
    const el = h("div", { class: "child", "data-child": r.name }, h("b", {}, r.name), h("small", {}, r.mri));
    el.addEventListener("pointerdown", (down) => {
      down.preventDefault();
      el.setPointerCapture(down.pointerId);
      const r = el.row;
      el.dragging = true;
      const start = [down.clientX, down.clientY];
      const from = [r.x, r.y];
      let at = from;
      const move = (e) => {
        at = [from[0] + e.clientX - start[0], from[1] + e.clientY - start[1]];
        el.style.left = `${ORIGIN + at[0]}px`;
        el.style.top = `${ORIGIN + at[1]}px`;
        r.x = at[0]; r.y = at[1];
        this.wire();
      };
      const up = () => {
        el.dragging = false;
        el.removeEventListener("pointermove", move);
        el.removeEventListener("pointerup", up);
        if (at !== from) this.call("set_position", { block_name: r.name, x: Math.round(at[0]), y: Math.round(at[1]) });
      };
      el.addEventListener("pointermove", move);
      el.addEventListener("pointerup", up);
    });
    return el;
  }

  async call(method, params) {
    try {
      await this.client.post([this.mri, method], params);
      this.status("");
    } catch (e) {
      this.status(e.message);
      if (this.layout) this.update(this.layout, this.wiring);
    }
  }

  wire() {
    const rows = (this.rows || []).filter((r) => r.visible);
    const owner = new Map(); // output port name -> row
    for (const r of rows) for (const p of ports(this.children.get(r.mri)?.data).sources) owner.set(p.name, r);
    const lines = [];
    const byName = new Map(rows.map((r) => [r.name, r]));
    const w = this.wiring || {};
    (w.sink || []).forEach((sink, i) => {
      const source = w.source[i];
      const from = byName.get(source.split(".")[0]), to = byName.get(sink.split(".")[0]);
      if (from && to && from !== to) lines.push([from, to, `${source} → ${sink}`]);
    });
    for (const r of rows) {
      for (const sink of ports(this.children.get(r.mri)?.data).sinks) {
        const from = owner.get(sink.source);
        if (!from || from === r) continue;
        lines.push([from, r, `${sink.source} → ${r.name}.${sink.field}`]);
      }
    }
    this.arrows.replaceChildren();
    const defs = document.createElementNS(NS, "defs");
    defs.innerHTML = '<marker id="wire-arrow" viewBox="0 0 10 10" refX="9" refY="5" markerWidth="7" markerHeight="7" orient="auto"><path d="M0 0L10 5L0 10z"/></marker>';
    this.arrows.append(defs);
    for (const [a, b, label] of lines) {
      const path = document.createElementNS(NS, "path");
      const x1 = ORIGIN + a.x + 110, y1 = ORIGIN + a.y + 20, x2 = ORIGIN + b.x, y2 = ORIGIN + b.y + 20;
      path.setAttribute("d", `M${x1} ${y1} C${x1 + 40} ${y1} ${x2 - 40} ${y2} ${x2} ${y2}`);
      path.setAttribute("marker-end", "url(#wire-arrow)");
      path.setAttribute("data-wire", label);
      const title = document.createElementNS(NS, "title");
      title.textContent = label;
      path.append(title);
      this.arrows.append(path);
    }
  }

  close() {
    for (const { sub } of this.children.values()) this.client.unsubscribe(sub);
    this.children.clear();
  }
}
