// A client of malcolm's JSON protocol (interop.md §3) over one WebSocket.
// Every request gets a fresh id; subscriptions keep a copy of the data up to
// date by applying each Delta, and call back with the whole copy.

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

export class Client {
  constructor(url) {
    this.url = url;
    this.nextId = 1;
    this.pending = new Map(); // id -> {resolve, reject}
    this.subs = new Map(); // id -> {callback, data}
    this.onstatus = () => {};
    this.ready = this.connect();
  }

  connect() {
    return new Promise((resolve, reject) => {
      const ws = new WebSocket(this.url);
      this.ws = ws;
      ws.onopen = () => { this.onstatus("connected"); resolve(); };
      ws.onerror = () => reject(new Error(`cannot reach ${this.url}`));
      ws.onclose = () => this.onstatus("disconnected");
      ws.onmessage = (event) => this.receive(JSON.parse(event.data));
    });
  }

  receive(msg) {
    const sub = this.subs.get(msg.id);
    if (msg.typeid === "malcolm:core/Delta:1.0" && sub) {
      sub.data = applyChanges(sub.data, msg.changes);
      sub.callback(sub.data, msg.changes);
      return;
    }
    if (msg.typeid === "malcolm:core/Update:1.0" && sub) {
      sub.data = msg.value;
      sub.callback(sub.data, null);
      return;
    }
    const waiting = this.pending.get(msg.id);
    if (!waiting) {
      if (msg.typeid === "malcolm:core/Error:1.0") console.warn(msg.message);
      return;
    }
    this.pending.delete(msg.id);
    if (msg.typeid === "malcolm:core/Error:1.0") waiting.reject(new Error(msg.message));
    else waiting.resolve(msg.value);
  }

  async send(message) {
    await this.ready;
    this.ws.send(JSON.stringify(message));
  }

  request(typeid, fields) {
    const id = this.nextId++;
    const reply = new Promise((resolve, reject) => this.pending.set(id, { resolve, reject }));
    this.send({ typeid: `malcolm:core/${typeid}:1.0`, id, ...fields });
    return reply;
  }

  get(path) { return this.request("Get", { path }); }
  put(path, value) { return this.request("Put", { path, value }); }
  post(path, parameters) { return this.request("Post", { path, parameters }); }

  // callback(data, changes) on the first value and after every change;
  // returns the subscription id (pass it to unsubscribe)
  subscribe(path, callback, delta = true) {
    const id = this.nextId++;
    this.subs.set(id, { callback, data: null });
    // an Error for this id (an unknown path) arrives as a rejected "request"
    this.pending.set(id, {
      resolve: () => {},
      reject: (e) => { this.subs.delete(id); callback(null, null, e); },
    });
    this.send({ typeid: "malcolm:core/Subscribe:1.0", id, path, delta });
    return id;
  }

  unsubscribe(id) {
    if (!this.subs.delete(id)) return;
    this.pending.set(id, { resolve: () => {}, reject: () => {} });
    this.send({ typeid: "malcolm:core/Unsubscribe:1.0", id });
  }
}
