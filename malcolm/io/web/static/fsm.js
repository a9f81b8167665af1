// A block's state machine drawn from its model (served at [".", "models", mri]):
// states in columns by their distance from the initial state, one arrow per
// source -> destination; the current state highlighted, the states passed
// through listed in the svg's data-trail.

const NS = "http://www.w3.org/2000/svg";
const W = 104, H = 26, DX = 140, DY = 40, PAD = 12;

function s(tag, attrs = {}, text) {
  const el = document.createElementNS(NS, tag);
  for (const [k, v] of Object.entries(attrs)) el.setAttribute(k, v);
  if (text !== undefined) el.textContent = text;
  return el;
}

function layers(model) {
  const next = new Map(model.states.map((st) => [st.name, []]));
  for (const t of model.transitions) next.get(t.source)?.push(t.dest);
  const depth = new Map([[model.initial, 0]]);
  const queue = [model.initial];
  while (queue.length) {
    const at = queue.shift();
    for (const d of next.get(at) || []) {
      if (!depth.has(d)) { depth.set(d, depth.get(at) + 1); queue.push(d); }
    }
  }
  let deepest = Math.max(0, ...depth.values());
  for (const st of model.states) if (!depth.has(st.name)) depth.set(st.name, ++deepest);
  const columns = [];
  for (const st of model.states) {
    const d = depth.get(st.name);
    (columns[d] ||= []).push(st.name);
  }
  const pos = new Map();
  columns.forEach((names, c) => names.forEach((n, r) => pos.set(n, [PAD + c * DX, PAD + r * DY])));
  const rows = Math.max(...columns.map((c) => c?.length || 0));
  return { pos, width: PAD * 2 + (columns.length - 1) * DX + W, height: PAD * 2 + (rows - 1) * DY + H };
}

export function drawModel(model) {
  const { pos, width, height } = layers(model);
  const svg = s("svg", { class: "fsm", viewBox: `0 0 ${width} ${height}`, width, height, "data-trail": "" });
  const defs = s("defs");
  const marker = s("marker", { id: "arrow", viewBox: "0 0 10 10", refX: 9, refY: 5, markerWidth: 6, markerHeight: 6, orient: "auto-start-reverse" });
  marker.append(s("path", { d: "M 0 0 L 10 5 L 0 10 z" }));
  defs.append(marker);
  svg.append(defs);
  const edges = s("g", { class: "edges" });
  const seen = new Map();
  // a state most states can move to (Fault, Disabling) is a "common" target:
  // its arrows are drawn faint, unless they leave the current state
  const sources = new Map();
  for (const t of model.transitions) {
    if (!sources.has(t.dest)) sources.set(t.dest, new Set());
    sources.get(t.dest).add(t.source);
  }
  const common = (dest) => (sources.get(dest)?.size || 0) >= model.states.length / 2;
  for (const t of model.transitions) {
    const key = `${t.source}>${t.dest}`;
    if (seen.has(key)) { seen.get(key).push(t.label); continue; }
    seen.set(key, [t.label]);
    const [x1, y1] = pos.get(t.source), [x2, y2] = pos.get(t.dest);
    const a = [x1 + W / 2, y1 + H / 2], b = [x2 + W / 2, y2 + H / 2];
    if (t.source === t.dest) {
      edges.append(s("path", { d: `M ${x1 + W - 20} ${y1} q 20 -18 20 6`, "data-edge": key, "marker-end": "url(#arrow)" }));
      continue;
    }
    // end on the destination's border; bend a little so A->B and B->A differ
    const dx = b[0] - a[0], dy = b[1] - a[1];
    const scale = Math.min(Math.abs((W / 2 + 2) / (dx || 1e-9)), Math.abs((H / 2 + 2) / (dy || 1e-9)));
    const end = [b[0] - dx * scale, b[1] - dy * scale];
    const mid = [(a[0] + end[0]) / 2 - dy * 0.08, (a[1] + end[1]) / 2 + dx * 0.08];
    edges.append(s("path", {
      d: `M ${a[0]} ${a[1]} Q ${mid[0]} ${mid[1]} ${end[0]} ${end[1]}`,
      "data-edge": key, "marker-end": "url(#arrow)", class: common(t.dest) ? "common" : "",
    }));
  }
  for (const [key, labels] of seen) edges.querySelector(`[data-edge="${CSS.escape(key)}"]`)?.append(s("title", {}, labels.join("\n")));
  svg.append(edges);
  for (const st of model.states) {
    const [x, y] = pos.get(st.name);
    const g = s("g", { class: `state${st.busy ? " busy" : ""}`, "data-state": st.name });
    g.append(s("rect", { x, y, width: W, height: H, rx: st.busy ? 13 : 4 }));
    g.append(s("text", { x: x + W / 2, y: y + H / 2 + 4, "text-anchor": "middle" }, st.name));
    g.append(s("title", {}, st.description || st.name));
    svg.append(g);
  }
  let current = null;
  svg.setState = (state) => {
    if (state === current) return;
    current = state;
    for (const g of svg.querySelectorAll(".state")) g.classList.toggle("current", g.dataset.state === state);
    // the moves possible from here stand out
    for (const p of svg.querySelectorAll("[data-edge]")) p.classList.toggle("out", p.dataset.edge.startsWith(`${state}>`));
    svg.dataset.trail = svg.dataset.trail ? `${svg.dataset.trail},${state}` : state;
    svg.dataset.current = state;
  };
  return svg;
}

// Whether the model lets `method` be called in `state` (unlisted: always).
export function allows(model, method, state) {
  const states = model?.methods?.[method];
  return !states || states.includes(state);
}
