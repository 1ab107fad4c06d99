// The connection to the bridge (docs/client-protocol.md): one WebSocket, JSON text frames.
// Sending never waits: a sample is dropped while the socket's send buffer is still full, so a
// slow network never stalls the render loop.
const MAX_BUFFERED = 64 * 1024;
const RETRY_MS = [500, 1000, 2000, 4000];

export class Bridge {
  constructor({ token, onMessage, onStatus }) {
    this.token = token;
    this.onMessage = onMessage;
    this.onStatus = onStatus;
    this.ws = null;
    this.state = 'connecting';
    this.retries = 0;
    this.sent = 0;
    this.skipped = 0;
    this.received = 0;
    this.pings = new Map();
    this.rttMs = null;
    this.pingId = 0;
    this.connect();
  }

  url() {
    const proto = window.location.protocol === 'https:' ? 'wss:' : 'ws:';
    const q = this.token ? `?token=${encodeURIComponent(this.token)}` : '';
    return `${proto}//${window.location.host}/ws${q}`;
  }

  setState(s, detail = '') {
    this.state = s;
    this.onStatus?.(s, detail);
  }

  connect() {
    const ws = new WebSocket(this.url());
    this.ws = ws;
    this.setState('connecting');
    ws.onopen = () => {
      this.retries = 0;
      this.setState('connected');
      ws.send(JSON.stringify({ type: 'subscribe', rate_hz: 90 }));
    };
    ws.onmessage = (ev) => {
      this.received++;
      let msg;
      try {
        msg = JSON.parse(ev.data);
      } catch {
        return;
      }
      if (msg.type === 'pong' && this.pings.has(msg.id)) {
        this.rttMs = performance.now() - this.pings.get(msg.id);
        this.pings.delete(msg.id);
      }
      this.onMessage(msg);
    };
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      const delay = RETRY_MS[Math.min(this.retries++, RETRY_MS.length - 1)];
      this.setState('disconnected', ev.reason || `code ${ev.code}`);
      setTimeout(() => this.connect(), delay);
    };
  }

  open() {
    return this.ws && this.ws.readyState === WebSocket.OPEN;
  }

  send(obj) {
    if (!this.open() || this.ws.bufferedAmount > MAX_BUFFERED) {
      this.skipped++;
      return false;
    }
    this.ws.send(JSON.stringify(obj));
    this.sent++;
    return true;
  }

  ping() {
    const id = ++this.pingId;
    const now = performance.now();
    this.pings.set(id, now);
    if (this.pings.size > 16) this.pings.delete(this.pings.keys().next().value);
    this.send({ type: 'ping', id, client_time_ms: now });
  }
}
