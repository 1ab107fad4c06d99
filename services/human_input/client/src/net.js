// The connection to the bridge (docs/client-protocol.md): one WebSocket, JSON text frames.
// Sending never waits: a sample is dropped while the socket's send buffer is still full, so a
// slow network never stalls the render loop. A heartbeat (a ping every HEARTBEAT_MS; frames and
// pongs keep the link alive) notices a link gone quiet within LOST_MS, even when the socket
// itself does not close, and reconnects. After the trial's end (rest()) nothing reconnects.
const MAX_BUFFERED = 64 * 1024;
const RETRY_MS = [500, 1000, 2000, 4000];
// The 4th beat after the last message finds the link lost (three silent beats spanning LOST_MS):
// 1.2-1.6 s after it went quiet, later by as much as a busy page runs its timers late (software
// rendering on a loaded machine). At 500 ms it was 1.5-2.0 s.
export const HEARTBEAT_MS = 400;
export const LOST_MS = 1200;
export const SILENT_BEATS = 3; // beats in a row that heard nothing (with LOST_MS): the link is lost
const DIAL_MS = 3000;
const DIAL_BEATS = 6;
export const FRAME_RATE_HZ = 90; // frames a second asked of the bridge (a headset's display rate)

export class Bridge {
  constructor({ token, driver, onMessage, onStatus, host = '', frameRateHz = FRAME_RATE_HZ }) {
    this.token = token;
    this.frameRateHz = frameRateHz; // frames a second asked of the bridge (subscribe)
    this.host = host; // host:port of the trial's bridge ('': the page's own server)
    this.driver = driver;
    // this page's own id: after a redial the bridge knows it is the same page (its hands, and
    // a part in them, are kept as they are)
    this.pageId = Math.random().toString(36).slice(2, 12);
    this.resting = false; // the trial is over: no reconnects, no errors
    this.lastHeardMs = performance.now();
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
    this.beatsMs = []; // when the last heartbeats ran (a busy page runs them late)
    this.heardSinceBeat = false; // (connect() starts the count of silent beats)
    this.connect();
  }

  url() {
    const proto = window.location.protocol === 'https:' ? 'wss:' : 'ws:';
    const q = new URLSearchParams();
    if (this.token) q.set('token', this.token);
    if (this.driver) q.set('driver', this.driver);
    q.set('page', this.pageId);
    const qs = q.toString();
    return `${proto}//${this.host || window.location.host}/ws${qs ? `?${qs}` : ''}`;
  }

  /** Asks the bridge for `hz` frames a second from now on (and after every reconnect). */
  setFrameRate(hz) {
    if (hz === this.frameRateHz) return;
    this.frameRateHz = hz;
    if (this.ws?.readyState === WebSocket.OPEN) this.subscribe(this.ws);
  }

  /** Tells the bridge over `ws` how many frames a second this page wants. */
  subscribe(ws) {
    ws.send(JSON.stringify({ type: 'subscribe', rate_hz: this.frameRateHz }));
  }

  setState(s, detail = '') {
    if (s === 'lost' && this.state !== 'lost') {
      this.lostAtMs = performance.now();
      this.heardBeforeLostMs = this.lastHeardMs; // when the link went quiet, as the page saw it
      this.beatsBeforeLostMs = [...this.beatsMs];
    }
    this.state = s;
    this.onStatus?.(s, detail);
  }

  connect() {
    if (this.resting) return;
    const ws = new WebSocket(this.url());
    this.ws = ws;
    this.lastHeardMs = performance.now();
    this.dialedMs = performance.now();
    this.dialBeats = 0;
    this.silentBeats = 0;
    this.setState(this.state === 'lost' ? 'lost' : 'connecting', this.state === 'lost' ? 'reconnecting' : '');
    ws.onopen = () => {
      this.lastHeardMs = performance.now();
      this.retries = 0;
      this.setState('connected');
      this.subscribe(ws);
    };
    ws.onmessage = (ev) => {
      if (this.ws !== ws) return;
      this.received++;
      this.lastHeardMs = performance.now();
      this.heardSinceBeat = true;
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
      if (this.resting) {
        this.setState('closed', 'the trial is over');
        return;
      }
      const delay = RETRY_MS[Math.min(this.retries++, RETRY_MS.length - 1)];
      this.setState('lost', 'reconnecting');
      setTimeout(() => this.connect(), delay);
    };
  }

  /** Called every HEARTBEAT_MS: pings, and gives up on a link that has gone quiet. Quiet is
   * judged in beats as well as in time: a page that is itself busy (long frames: software
   * rendering on a loaded machine) runs its beats late, and what the link sent meanwhile may
   * still wait behind them; only SILENT_BEATS beats in a row that heard nothing, spanning
   * LOST_MS, make a lost link. */
  heartbeat() {
    const now = performance.now();
    this.beatsMs = [...this.beatsMs.slice(-7), now];
    this.silentBeats = this.heardSinceBeat ? 0 : this.silentBeats + 1;
    this.heardSinceBeat = false;
    const quiet = this.silentBeats >= SILENT_BEATS && now - this.lastHeardMs > LOST_MS;
    if (this.resting) {
      // the bridge stays up a moment after the end; a quiet link then is no loss
      if (this.state === 'connected' && quiet) this.setState('closed', 'the trial is over');
      return;
    }
    if (this.open()) this.ping();
    if (this.state === 'connected' && quiet) {
      // the socket may take minutes to notice a dead link: drop it and dial again
      this.setState('lost', 'reconnecting');
      this.redial();
    } else if (this.state !== 'connected' && !this.open()) {
      this.dialBeats += 1;
      if (this.dialBeats >= DIAL_BEATS && now - this.dialedMs > DIAL_MS) this.redial();
    }
  }

  /** Drops the socket (a dead link, or a dial that neither opens nor fails) and dials again. */
  redial() {
    const old = this.ws;
    this.ws = null;
    try {
      old?.close();
    } catch {
      // closing a socket that never opened
    }
    this.connect();
  }

  /** The trial is over: the last frames still come until the bridge closes; then the page
   * stays as it is, never reconnects, shows no error. */
  rest() {
    this.resting = true;
    if (!this.open()) this.setState('closed', 'the trial is over');
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
