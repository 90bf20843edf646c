// ikbench experiment: the lab's touchscreen page (ikbench/experiment/touchscreen.py). The SVG's
// viewBox is the screen's size in pixels, so a touch's coordinates are the screen's pixels.
"use strict";

const touch = window.touch = { state: { phase: "loading" }, layout: null, sent: 0 };
const svg = document.getElementById("screen");
const NS = "http://www.w3.org/2000/svg";

function el(name, attrs) {
  const e = document.createElementNS(NS, name);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  return e;
}

async function json(url, body) {
  const reply = await fetch(url, body === undefined ? { cache: "no-store" }
    : { method: "POST", headers: { "Content-Type": "application/json" }, body: JSON.stringify(body) });
  return { status: reply.status, body: await reply.json() };
}

function render(state) {
  const panel = document.getElementById("panel");
  const screenOn = ["instructions", "break", "done"].includes(state.phase);
  panel.classList.toggle("on", screenOn);
  document.getElementById("text").textContent = state.message || "";
  document.getElementById("go").style.display = state.phase === "done" ? "none" : "";
}

async function poll() {
  for (;;) {
    try {
      const reply = await json("/api/state");
      if (reply.status === 200) {
        if (reply.body.token !== touch.state.token) render(reply.body);
        touch.state = reply.body;
      }
    } catch (e) { /* the server is away: keep polling */ }
    await new Promise((r) => setTimeout(r, 50));
  }
}

async function start() {
  const reply = await json("/api/layout");
  const layout = touch.layout = reply.body;
  svg.setAttribute("viewBox", `0 0 ${layout.screen_px[0]} ${layout.screen_px[1]}`);
  svg.appendChild(el("rect", { x: 0, y: 0, width: layout.screen_px[0], height: layout.screen_px[1], fill: "#3a3f47" }));
  for (const p of Object.values(layout.targets)) {
    svg.appendChild(el("circle", { cx: p[0], cy: p[1], r: layout.radius_px, fill: "#f2f2f2", stroke: "#9aa3ad", "stroke-width": 4 }));
  }
  const mark = el("circle", { cx: -100, cy: -100, r: 14, fill: "#e2574c" });
  svg.appendChild(mark);
  svg.addEventListener("pointerdown", async (event) => {
    const point = svg.createSVGPoint();
    point.x = event.clientX; point.y = event.clientY;
    const px = point.matrixTransform(svg.getScreenCTM().inverse());
    const s = touch.state;
    if (s.trial === null || s.trial === undefined) return;
    mark.setAttribute("cx", px.x); mark.setAttribute("cy", px.y);
    touch.sent += 1;
    await json("/api/touch", { trial: s.trial, attempt: s.attempt, x_px: px.x, y_px: px.y });
  });
  document.getElementById("go").addEventListener("click", async () => {
    if (document.documentElement.requestFullscreen && !document.fullscreenElement) {
      document.documentElement.requestFullscreen().catch(() => {});
    }
    await json("/api/continue", { token: touch.state.token });
  });
  poll();
}

start();
