// A client of malcolm's JSON protocol (interop.md §3) over one WebSocket.
// Every request gets a fresh id; subscriptions keep a copy of the data up to
// date by applying each Delta, and call back with the whole copy. A lost
// connection is made again every RETRY ms; then every subscription is made
// again (its first reply replaces the copy), and calls that were waiting
// fail with "connection lost".

export function applyChanges(data, changes) {
  for (const change of changes) {
    const [path, ...rest] = change;
    if (path.length === 0) {
      data = rest.length ? structuredClone(rest[0]) : null;
      continue;
    }
    let parent = data;
    for (const key of path.slice(0, -1)) parent = parent[key];
    const last = path[path.length - 1];
    if (rest.length) parent[last] = structuredClone(rest[0]);
    else delete parent[last];
  }
  return data;
}

const T = (name) => `malcolm:core/${name}:1.0`;

export class Client {
  static RETRY = 2000;

  constructor(url) {
    this.url = url;
    this.nextId = 1;
    this.pending = new Map(); // id -> {resolve, reject}
    this.subs = new Map(); // id -> {callback, data, path, delta}
    this.outbox = []; // what waits for the connection
    this.onstatus = () => {};
    this.connect();
  }

  connect() {
    const ws = new WebSocket(this.url);
    this.ws = ws;
    ws.onopen = () => {
      this.onstatus("connected");
      for (const [id, sub] of this.subs) {
        ws.send(JSON.stringify({ typeid: T("Subscribe"), id, path: sub.path, delta: sub.delta }));
      }
      for (const text of this.outbox.splice(0)) ws.send(text);
    };
    ws.onclose = () => {
      this.onstatus("disconnected");
      for (const [id, waiting] of [...this.pending]) {
        if (this.subs.has(id)) continue;
        this.pending.delete(id);
        waiting.reject(new Error("connection lost"));
      }
      setTimeout(() => this.connect(), Client.RETRY);
    };
    ws.onmessage = (event) => this.receive(JSON.parse(event.data));
  }

  receive(msg) {
    const sub = this.subs.get(msg.id);
    if (msg.typeid === T("Delta") && sub) {
      sub.data = applyChanges(sub.data, msg.changes);
      sub.callback(sub.data, msg.changes);
      return;
    }
    if (msg.typeid === T("Update") && sub) {
      sub.data = msg.value;
      sub.callback(sub.data, null);
      return;
    }
    const waiting = this.pending.get(msg.id);
    if (!waiting) {
      if (msg.typeid === T("Error")) console.warn(msg.message);
      return;
    }
    this.pending.delete(msg.id);
    if (msg.typeid === T("Error")) waiting.reject(new Error(msg.message));
    else waiting.resolve(msg.value);
  }

  send(message, always = true) {
    const text = JSON.stringify(message);
    if (this.ws.readyState === WebSocket.OPEN) this.ws.send(text);
    else if (always) this.outbox.push(text);
  }

  request(typeid, fields) {
    const id = this.nextId++;
    const reply = new Promise((resolve, reject) => this.pending.set(id, { resolve, reject }));
    this.send({ typeid: T(typeid), id, ...fields });
    return reply;
  }

  get(path) { return this.request("Get", { path }); }
  put(path, value) { return this.request("Put", { path, value }); }
  post(path, parameters) { return this.request("Post", { path, parameters }); }

  // callback(data, changes) on the first value and after every change, or
  // callback(null, null, error) if the path is refused; returns the
  // subscription's id (pass it to unsubscribe)
  subscribe(path, callback, delta = true) {
    const id = this.nextId++;
    this.subs.set(id, { callback, data: null, path, delta });
    this.pending.set(id, {
      resolve: () => {},
      reject: (e) => { this.subs.delete(id); callback(null, null, e); },
    });
    // not connected: the connection's opening subscribes it
    this.send({ typeid: T("Subscribe"), id, path, delta }, false);
    return id;
  }

  unsubscribe(id) {
    if (!this.subs.delete(id)) return;
    this.pending.set(id, { resolve: () => {}, reject: () => {} });
    this.send({ typeid: T("Unsubscribe"), id }, false);
  }
}
