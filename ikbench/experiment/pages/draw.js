// ikbench experiment: draw the shapes the server projected (ikbench/experiment/scene.py) on a
// 2-D canvas. No WebGL, no library: a laptop browser without a GPU draws them.
"use strict";

const IkbDraw = (() => {
  // Fit a canvas to its box keeping the view's aspect; returns view units -> CSS px scale.
  function fit(canvas, view) {
    const box = canvas.parentElement.getBoundingClientRect();
    const scale = Math.min(box.width / view[0], box.height / view[1]);
    const ratio = window.devicePixelRatio || 1;
    canvas.style.width = `${view[0] * scale}px`;
    canvas.style.height = `${view[1] * scale}px`;
    canvas.width = Math.round(view[0] * scale * ratio);
    canvas.height = Math.round(view[1] * scale * ratio);
    const ctx = canvas.getContext("2d");
    ctx.setTransform(scale * ratio, 0, 0, scale * ratio, 0, 0);
    return ctx;
  }

  // Paint far to near (the server's depth z; a stable sort keeps a part's shapes in order).
  function paint(ctx, view, shapes, background) {
    ctx.fillStyle = background || "#f4f5f7";
    ctx.fillRect(0, 0, view[0], view[1]);
    const order = shapes.slice().sort((a, b) => b.z - a.z);
    for (const s of order) {
      if (!s.pts.length) continue;
      ctx.beginPath();
      ctx.moveTo(s.pts[0][0], s.pts[0][1]);
      for (let i = 1; i < s.pts.length; i++) ctx.lineTo(s.pts[i][0], s.pts[i][1]);
      if (s.type === "poly") {
        ctx.closePath();
        ctx.fillStyle = s.fill;
        ctx.fill();
        if (s.stroke) { ctx.strokeStyle = s.stroke; ctx.lineWidth = s.lw; ctx.stroke(); }
      } else {
        ctx.strokeStyle = s.color;
        ctx.lineWidth = s.lw;
        ctx.lineCap = "round";
        ctx.lineJoin = "round";
        ctx.stroke();
      }
    }
  }

  // 3x3 homography helpers: screen px <-> view units.
  function apply(h, x, y) {
    const w = h[2][0] * x + h[2][1] * y + h[2][2];
    return [(h[0][0] * x + h[0][1] * y + h[0][2]) / w, (h[1][0] * x + h[1][1] * y + h[1][2]) / w];
  }
  function invert(m) {
    const [a, b, c] = m[0], [d, e, f] = m[1], [g, h, i] = m[2];
    const A = e * i - f * h, B = -(d * i - f * g), C = d * h - e * g;
    const det = a * A + b * B + c * C;
    return [[A / det, -(b * i - c * h) / det, (b * f - c * e) / det],
            [B / det, (a * i - c * g) / det, -(a * f - c * d) / det],
            [C / det, -(a * h - b * g) / det, (a * e - b * d) / det]];
  }
  // View units under a mouse event on the canvas.
  function viewOf(canvas, view, event) {
    const r = canvas.getBoundingClientRect();
    return [(event.clientX - r.left) * view[0] / r.width, (event.clientY - r.top) * view[1] / r.height];
  }
  return { fit, paint, apply, invert, viewOf };
})();
