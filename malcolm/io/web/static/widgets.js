// Widgets chosen from metas: an attribute's editor or display, and a
// method's form built from its takes and defaults.

export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k === "class") el.className = v;
    else if (k.startsWith("on")) el.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) el.setAttribute(k, v === true ? "" : v);
  }
  for (const c of children.flat()) if (c !== null && c !== undefined) el.append(c);
  return el;
}

const kind = (meta) => (meta?.typeid || "").replace("malcolm:core/", "").replace(/:.*/, "");
const hasTag = (meta, tag) => (meta?.tags || []).includes(tag);

function limits(meta) {
  const d = meta.display || {};
  return d.limitLow < d.limitHigh ? [d.limitLow, d.limitHigh] : null;
}

export function describeValue(value) {
  if (value === null || value === undefined) return "";
  if (typeof value === "object") return JSON.stringify(value);
  return String(value);
}

// An editor for one value of `meta`: {el, get(), set(value)}.
// `commit(value)` is called when the user changes it (attributes put at once).
export function editor(meta, commit, name) {
  const k = kind(meta);
  const writeable = meta.writeable !== false;
  const changed = () => commit && commit(ed.get());
  let ed;
  if (k === "BooleanMeta") {
    if (!writeable || hasTag(meta, "widget:led")) {
      const el = h("span", { class: "led", "data-name": name });
      ed = { el, get: () => el.classList.contains("on"), set: (v) => el.classList.toggle("on", !!v) };
    } else {
      const el = h("input", { type: "checkbox", "data-name": name, onchange: changed });
      ed = { el, get: () => el.checked, set: (v) => { el.checked = !!v; } };
    }
  } else if (k === "ChoiceMeta") {
    const el = h("select", { "data-name": name, onchange: changed, disabled: !writeable },
      (meta.choices || []).map((c) => h("option", { value: c }, c)));
    ed = { el, get: () => el.value, set: (v) => { if (document.activeElement !== el) el.value = v; } };
  } else if (k === "NumberMeta") {
    const lim = limits(meta);
    const units = meta.display?.units;
    const isInt = /int/.test(meta.dtype || "");
    const input = h("input", {
      type: "number", "data-name": name, readonly: !writeable,
      step: isInt ? "1" : "any", min: lim?.[0], max: lim?.[1],
      onchange: changed, onkeydown: (e) => e.key === "Enter" && input.blur(),
    });
    const el = h("span", { class: "number" }, input,
      units ? h("span", { class: "units" }, units) : null,
      lim ? h("span", { class: "limits" }, `[${lim[0]}, ${lim[1]}]`) : null);
    ed = {
      el,
      get: () => (input.value === "" ? null : Number(input.value)),
      set: (v) => { if (document.activeElement !== input) input.value = v ?? ""; },
    };
  } else if (k === "TableMeta") {
    ed = tableEditor(meta, commit, name);
  } else if (k === "StringMeta") {
    const input = h("input", { type: "text", "data-name": name, readonly: !writeable, onchange: changed });
    ed = { el: input, get: () => input.value, set: (v) => { if (document.activeElement !== input) input.value = v ?? ""; } };
  } else {
    // arrays, generators and anything else: JSON text
    const big = k === "PointGeneratorMeta";
    const input = h(big ? "textarea" : "input", {
      type: "text", "data-name": name, readonly: !writeable, onchange: changed,
      placeholder: big ? '{"typeid": "scanpointgenerator:generator/CompoundGenerator:1.0", ...}' : "JSON",
      rows: big ? 4 : undefined,
    });
    ed = {
      el: input,
      get: () => (input.value.trim() === "" ? null : JSON.parse(input.value)),
      set: (v) => { if (document.activeElement !== input) input.value = v === null || v === undefined ? "" : JSON.stringify(v); },
    };
  }
  return ed;
}

// A table of inputs, one column per element meta; "put" sends the whole table.
function tableEditor(meta, commit, name) {
  const columns = Object.keys(meta.elements || {});
  const writeable = meta.writeable !== false;
  // columns say which of them may be edited only if some of them may
  const perColumn = columns.some((c) => meta.elements[c].writeable);
  const body = h("tbody");
  let rows = [];
  const draw = () => {
    body.replaceChildren(...rows.map((row, r) => h("tr", {},
      columns.map((c) => {
        const column = meta.elements[c];
        const cellMeta = {
          ...column,
          typeid: (column.typeid || "").replace("ArrayMeta", "Meta"),
          writeable: writeable && (!perColumn || column.writeable !== false),
        };
        const cell = editor(cellMeta, null, `${name}.${r}.${c}`);
        cell.set(row[c]);
        cell.el.addEventListener("change", () => { row[c] = cell.get(); dirty(true); });
        return h("td", {}, cell.el);
      }),
      writeable ? h("td", {}, h("button", { class: "small", onclick: () => { rows.splice(r, 1); draw(); dirty(true); } }, "−")) : null)));
  };
  let isDirty = false;
  const putButton = h("button", { class: "small", "data-name": `${name}.put`, onclick: () => { commit(ed.get()); dirty(false); } }, "put table");
  const dirty = (v) => { isDirty = v; putButton.classList.toggle("dirty", v); };
  const el = h("div", { class: "table", "data-name": name },
    h("table", {}, h("thead", {}, h("tr", {}, columns.map((c) => h("th", {}, c)))), body),
    writeable && commit ? h("div", {},
      h("button", { class: "small", onclick: () => { const row = {}; for (const c of columns) row[c] = null; rows.push(row); draw(); dirty(true); } }, "+ row"),
      putButton) : null);
  const ed = {
    el,
    get: () => {
      const out = {};
      for (const c of columns) out[c] = rows.map((row) => row[c]);
      return out;
    },
    set: (v) => {
      if (isDirty || el.contains(document.activeElement)) return;
      const n = columns.length ? (v?.[columns[0]] || []).length : 0;
      rows = Array.from({ length: n }, (_, i) => Object.fromEntries(columns.map((c) => [c, v[c][i]])));
      draw();
    },
  };
  return ed;
}

const SEVERITY = ["", "minor", "major", "invalid", "undefined"];

// One attribute's row: label, widget, alarm. update(data) refreshes it.
export function attributeRow(client, mri, name, data) {
  const meta = data.meta || {};
  let ed;
  const status = h("span", { class: "status" });
  const rebuild = (m) => {
    ed = editor(m, async (value) => {
      status.textContent = "";
      try {
        await client.put([mri, name, "value"], value);
      } catch (e) {
        status.textContent = e.message;
        status.className = "status error";
      }
    }, name);
  };
  rebuild(meta);
  const alarm = h("span", { class: "alarm" });
  const slot = h("span", { class: "widget" }, ed.el);
  const row = h("div", { class: "attr", "data-attr": name, title: meta.description || "" },
    h("label", {}, meta.label || name), slot, alarm, status);
  let metaText = JSON.stringify(meta);
  const update = (d) => {
    const text = JSON.stringify(d.meta || {});
    if (text !== metaText) { metaText = text; rebuild(d.meta || {}); slot.replaceChildren(ed.el); }
    ed.set(d.value);
    const sev = d.alarm?.severity || 0;
    row.dataset.severity = SEVERITY[sev] || "";
    alarm.textContent = sev ? d.alarm.message || SEVERITY[sev] : "";
  };
  update(data);
  return { el: row, update };
}

// What a method's form is built from: a form is rebuilt when it changes.
export const methodKey = (data) => JSON.stringify([data.meta?.takes, data.meta?.defaults]);

// One method's form: an input per `takes` element with its default, a button.
export function methodForm(client, mri, name, data) {
  const meta = data.meta || {};
  const takes = meta.takes?.elements || {};
  const required = meta.takes?.required || [];
  const defaults = meta.defaults || {};
  const inputs = {};
  const fields = Object.entries(takes).map(([arg, m]) => {
    const ed = editor({ ...m, writeable: true }, null, `${name}.${arg}`);
    if (arg in defaults) ed.set(defaults[arg]);
    inputs[arg] = ed;
    return h("label", { class: "arg", title: m.description || "" },
      h("span", {}, arg + (required.includes(arg) ? "*" : "")), ed.el);
  });
  const result = h("pre", { class: "result", "data-result": name });
  const button = h("button", { "data-method": name, onclick: async () => {
    const params = {};
    try {
      for (const [arg, ed] of Object.entries(inputs)) {
        const v = ed.get();
        if (v !== null && v !== "" && !(Array.isArray(v) && v.length === 0 && !(arg in defaults))) params[arg] = v;
      }
    } catch (e) {
      result.className = "result error";
      result.textContent = `bad argument: ${e.message}`;
      return;
    }
    result.className = "result busy";
    result.textContent = "…";
    try {
      const value = await client.post([mri, name], params);
      result.className = "result ok";
      result.textContent = value === null || value === undefined ? "done" : JSON.stringify(value, null, 1);
    } catch (e) {
      result.className = "result error";
      result.textContent = e.message;
    }
  } }, meta.label || name);
  const el = h("div", { class: "method", "data-method-form": name, title: meta.description || "" },
    h("div", { class: "args" }, button, fields), result);
  return {
    el,
    key: methodKey(data),
    enable: (allowed) => { button.disabled = !allowed; el.classList.toggle("disallowed", !allowed); },
  };
}
