// The link to a session (`hrc session`, docs/client-protocol.md "Sessions"): one WebSocket to
// /session on the page's own server. It carries the screens between trials and what the
// participant answers; it redials whenever it drops (the session outlives a lost link: the
// server sends the screen showing now again on reconnection).
const RETRY_MS = [500, 1000, 2000, 3000];

export class SessionLink {
  constructor({ token, driver, onScreen, onStatus }) {
    this.token = token;
    this.driver = driver;
    this.onScreen = onScreen;
    this.onStatus = onStatus;
    this.retries = 0;
    this.state = 'connecting';
    this.connect();
  }

  url() {
    const proto = window.location.protocol === 'https:' ? 'wss:' : 'ws:';
    const q = new URLSearchParams();
    if (this.token) q.set('token', this.token);
    if (this.driver) q.set('driver', this.driver);
    return `${proto}//${window.location.host}/session?${q}`;
  }

  connect() {
    const ws = new WebSocket(this.url());
    this.ws = ws;
    ws.onopen = () => {
      this.retries = 0;
      this.state = 'connected';
      this.onStatus?.('connected');
    };
    // (onclose below is called for a refused dial too: the browser does not say why)
    ws.onmessage = (ev) => {
      let msg;
      try {
        msg = JSON.parse(ev.data);
      } catch {
        return;
      }
      if (msg.type === 'screen') {
        this.last = msg.kind;
        this.onScreen(msg);
      }
    };
    ws.onclose = (ev) => {
      if (this.ws !== ws) return;
      this.state = 'lost';
      // 4000: another page of the participant took over; it is the one that goes on
      if (ev.code === 4000) {
        this.onStatus?.('replaced');
        return;
      }
      // the session is over (its server goes a moment after its last screen): nothing to redial
      if (this.last === 'done' || this.last === 'ended') {
        this.onStatus?.('over');
        return;
      }
      this.onStatus?.('lost');
      const delay = RETRY_MS[Math.min(this.retries++, RETRY_MS.length - 1)];
      if (this.retries >= 3) this.check(); // down for a few seconds: is it gone, or this key?
      setTimeout(() => this.connect(), delay);
    };
  }

  /** Asks the page's server whether this link's key still opens the session: 'refused' if
   * not (the session was begun anew: this link is not the participant's any more), 'away'
   * if nobody answers (the session is stopped; it goes on when it is started again). */
  async check() {
    const q = new URLSearchParams();
    if (this.token) q.set('token', this.token);
    if (this.driver) q.set('driver', this.driver);
    let state = 'away';
    try {
      const r = await fetch(`/session?${q}`, { cache: 'no-store' });
      if (r.status === 401 || r.status === 403) state = 'refused';
      else if (r.ok) return; // it answers: the next dial gets through
    } catch {
      // no answer: the session's process is not running
    }
    if (this.state === 'lost') this.onStatus?.(state);
  }

  send(obj) {
    if (!this.ws || this.ws.readyState !== WebSocket.OPEN) return false;
    this.ws.send(JSON.stringify(obj));
    return true;
  }
}
