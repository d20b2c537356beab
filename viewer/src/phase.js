// The phase-space path of a multi-robot schedule (paper 002 §V, Fig. 9): P = [0,1]^n, the
// scheduler's path from (0,…,0) to (1,…,1) in green and the current phase as a red dot. Two
// robots: one square; three or more: the projection on a pair of robots chosen in the page
// (or on every pair).

const PAD = 22;

function pairs(n) {
  const out = [];
  for (let i = 0; i < n; i++) for (let j = i + 1; j < n; j++) out.push([i, j]);
  return out;
}

function drawPanel(ctx, x0, y0, size, i, j, phase, current) {
  const px = (u) => x0 + PAD + u * (size - 2 * PAD);
  const py = (v) => y0 + size - PAD - v * (size - 2 * PAD);
  ctx.strokeStyle = '#888';
  ctx.lineWidth = 1;
  ctx.strokeRect(px(0), py(1), size - 2 * PAD, size - 2 * PAD);
  ctx.fillStyle = '#333';
  ctx.font = '11px sans-serif';
  ctx.fillText(`φ ${phase.robots[i]}`, px(0), y0 + size - 5);
  ctx.save();
  ctx.translate(x0 + 11, py(0));
  ctx.rotate(-Math.PI / 2);
  ctx.fillText(`φ ${phase.robots[j]}`, 0, 0);
  ctx.restore();
  ctx.strokeStyle = '#1a9a3a';
  ctx.lineWidth = 2;
  ctx.beginPath();
  phase.path.forEach((p, k) => {
    if (k === 0) ctx.moveTo(px(p[i]), py(p[j]));
    else ctx.lineTo(px(p[i]), py(p[j]));
  });
  ctx.stroke();
  if (current && current.length > Math.max(i, j)) {
    ctx.fillStyle = '#d02020';
    ctx.beginPath();
    ctx.arc(px(current[i]), py(current[j]), 4, 0, 2 * Math.PI);
    ctx.fill();
  }
}

/** The robot pairs of an n-robot phase path, as `[i, j]` with i < j. */
export function phasePairs(n) {
  return pairs(n);
}

/**
 * Draws the phase path of `phase` (`{robots, path}`) with `current` marked on `canvas`: one
 * panel per pair of robots, or only the pairs in `shown` (indices into `phasePairs`).
 */
export function drawPhase(canvas, phase, current, shown = null) {
  const n = phase.robots.length;
  const all = pairs(n);
  const ps = shown ? shown.map((k) => all[k]).filter(Boolean) : all;
  const size = 220;
  const w = size * ps.length;
  if (canvas.width !== w || canvas.height !== size) {
    canvas.width = w;
    canvas.height = size;
  }
  const ctx = canvas.getContext('2d');
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  ctx.fillStyle = 'rgba(255,255,255,0.92)';
  ctx.fillRect(0, 0, canvas.width, canvas.height);
  ps.forEach(([i, j], k) => drawPanel(ctx, k * size, 0, size, i, j, phase, current));
}
