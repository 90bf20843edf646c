// ikbench experiment: the participant page of the online study (ikbench/experiment/online.py).
// The next trial always comes from the server (records.next_trial), so a reload resumes; an
// answer is kept here and posted again until the server replies (a 409 then means it was
// recorded already or is stale: nothing is recorded twice).
"use strict";

const study = window.study = { phase: "loading", participant: null, trial: null, attempt: null,
  current: null, pending: null, recorded: 0, error: null };
const $ = (id) => document.getElementById(id);
const canvas = $("view");
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const INTER_TRIAL_MS = 600;

function show(card) {
  for (const c of document.querySelectorAll(".card")) c.classList.toggle("on", c.id === card);
}

// fetch JSON, retrying while the server cannot be reached (it may be restarting)
async function call(url, options) {
  for (let wait = 250; ; wait = Math.min(wait * 2, 2000)) {
    try {
      const reply = await fetch(url, { cache: "no-store", ...options });
      $("offline").style.display = "none";
      let body = {};
      try { body = await reply.json(); } catch (e) { body = {}; }
      return { status: reply.status, body };
    } catch (e) {
      $("offline").style.display = "block";
      study.offline = true;
      await sleep(wait);
    }
  }
}

function message(title, text, button) {
  $("message-title").textContent = title;
  $("message-text").textContent = text;
  $("message-go").textContent = button || "Continue";
  show("card-message");
  study.phase = "message";
  return new Promise((resolve) => {
    $("message-go").onclick = () => { show(null); resolve(); };
  });
}

function flash(text, ms) {
  $("flash").textContent = text;
  $("flash").style.display = "block";
  setTimeout(() => { $("flash").style.display = "none"; }, ms || 900);
}

let ctx = null;
function draw(frame) {
  const t = study.current;
  if (!t) return;
  ctx = IkbDraw.fit(canvas, t.view);
  IkbDraw.paint(ctx, t.view, t.static.concat(t.frames[frame]));
  study.frame = frame;
}
window.addEventListener("resize", () => { if (study.current) draw(study.frame || 0); });

function progress(t) {
  const share = t.total ? t.answered / t.total : 0;
  $("progress").firstElementChild.style.width = `${100 * share}%`;
  $("count").textContent = `${t.answered} of ${t.total} answered`;
  $("where").textContent = t.done ? "done" : t.practice ? "practice"
    : `block ${t.block_number} of ${t.blocks}`;
}

function play(t) {
  return new Promise((resolve) => {
    const start = performance.now();
    const step = () => {
      const now = (performance.now() - start) / 1000;
      let i = 0;
      while (i + 1 < t.times_s.length && t.times_s[i + 1] <= now) i++;
      draw(i);
      if (i + 1 < t.times_s.length) requestAnimationFrame(step); else resolve();
    };
    requestAnimationFrame(step);
  });
}

function awaitClick(t) {
  return new Promise((resolve) => {
    const inverse = IkbDraw.invert(t.homography);
    const t0 = performance.now();
    study.phase = "awaiting";
    const timer = setTimeout(() => { finish({ timed_out: true }); }, t.response_window_s * 1000);
    function finish(answer) {
      clearTimeout(timer);
      canvas.onpointerdown = null;
      resolve(answer);
    }
    canvas.onpointerdown = (event) => {
      const reaction = (performance.now() - t0) / 1000;
      const v = IkbDraw.viewOf(canvas, t.view, event);
      const px = IkbDraw.apply(inverse, v[0], v[1]);
      if (px[0] < 0 || px[1] < 0 || px[0] > t.screen_px[0] || px[1] > t.screen_px[1]) return;
      if (reaction > t.response_window_s) { finish({ timed_out: true }); return; }
      ctx.fillStyle = "#e2574c";
      ctx.beginPath(); ctx.arc(v[0], v[1], 6, 0, 2 * Math.PI); ctx.fill();
      finish({ timed_out: false, touch_x_px: px[0], touch_y_px: px[1], reaction_s: reaction });
    };
  });
}

async function send(answer) {
  study.pending = answer;
  study.phase = "sending";
  const reply = await call("/api/response", { method: "POST",
    headers: { "Content-Type": "application/json" }, body: JSON.stringify(answer) });
  study.pending = null;
  if (reply.status === 200) { study.recorded += 1; return true; }
  if (reply.status === 409) return false;            // recorded already, or a stale tab
  study.error = reply.body.error || `HTTP ${reply.status}`;
  await message("Something went wrong", study.error + " - please tell the researcher.", "Retry");
  return false;
}

async function run() {
  let first = true;
  for (;;) {
    study.phase = "loading";
    const reply = await call(`/api/next?participant=${encodeURIComponent(study.participant)}`);
    if (reply.status !== 200) {
      await message("Unknown participant", reply.body.error || "", "Retry");
      continue;
    }
    const t = reply.body;
    progress(t);
    if (t.done) {
      study.phase = "done";
      await message("Thank you!", "You have answered every trial. You can close this page.", "Close");
      study.phase = "done";
      return;
    }
    if (first && t.started) await message("Welcome back", "The study continues where it stopped.");
    else if (first) {
      await message("Instructions", study.settings.instructions, "Start");
    } else if (t.practice_over) {
      await message("Practice over", "The study begins now. Take a short break if you like.");
    } else if (t.break_before) {
      await message("Break", "Take a short break. Continue when you are ready.");
    }
    first = false;
    study.current = t; study.trial = t.trial; study.attempt = t.attempt;
    study.phase = "rest";
    draw(0);
    await sleep(INTER_TRIAL_MS);
    study.phase = "moving";
    await play(t);
    const answer = await awaitClick(t);
    if (answer.timed_out) flash("Too slow - this one comes again later", 1000);
    await send({ participant: study.participant, trial: t.trial, attempt: t.attempt, ...answer });
  }
}

async function start() {
  const settings = await call("/api/study");
  study.settings = settings.body;
  const given = new URLSearchParams(location.search).get("participant");
  if (given) { study.participant = given; }
  else {
    study.phase = "id";
    show("card-id");
    study.participant = await new Promise((resolve) => {
      $("id-form").onsubmit = async (event) => {
        event.preventDefault();
        const id = $("id-input").value.trim();
        const reply = await call(`/api/next?participant=${encodeURIComponent(id)}`);
        if (reply.status === 200) resolve(id); else $("id-error").textContent = reply.body.error;
      };
    });
    show(null);
  }
  const probe = await call(`/api/next?participant=${encodeURIComponent(study.participant)}`);
  if (probe.status === 200 && !probe.body.started && !probe.body.done) {
    $("consent-text").textContent = study.settings.consent;
    $("consent-text").classList.toggle("placeholder", study.settings.consent_is_placeholder);
    show("card-consent");
    study.phase = "consent";
    await new Promise((resolve) => { $("consent-yes").onclick = () => { show(null); resolve(); }; });
  }
  await run();
}

start();
