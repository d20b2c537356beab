// The plan's motion on one time axis: joint tracks, grasp/release events and the multi-robot
// phase path, read from a plan job's result as the manyhands API returns it.
//
// Sources, best first (what the API answers today, and older results without timing):
//   1. `result.trajectory` — one JointTrajectory (trajectory_msgs shape) whose `joint_names` are
//      the result's `variables` ("robot/joint"), sampled on the plan's clock;
//   2. `result.trajectories` — multi-robot: `{robot: JointTrajectory}` on one common clock;
//   3. `result.schedule.points` — a multi-robot schedule's knots (phase, per-robot positions,
//      `time_from_start`), joints from `result.robots[i].variables` or the request's trajectories;
//   4. bare `variables` + `waypoints` — timed here only for display, every joint at most
//      UNTIMED_SPEED per second along each segment (the page says so).

export const UNTIMED_SPEED = 1.0;

/** A piecewise-linear track of named variables over time. */
export class Track {
  constructor(names, times, values) {
    this.names = names;
    this.times = times;
    this.values = values;
  }

  get duration() {
    return this.times.length ? this.times[this.times.length - 1] : 0;
  }

  /** Values at time t (clamped to the track), linearly interpolated between samples. */
  at(t) {
    const ts = this.times;
    const n = ts.length;
    if (n === 0) return [];
    if (t <= ts[0]) return this.values[0];
    if (t >= ts[n - 1]) return this.values[n - 1];
    let lo = 0;
    let hi = n - 1;
    while (hi - lo > 1) {
      const mid = (lo + hi) >> 1;
      if (ts[mid] <= t) lo = mid;
      else hi = mid;
    }
    const span = ts[hi] - ts[lo];
    const s = span > 0 ? (t - ts[lo]) / span : 0;
    const a = this.values[lo];
    const b = this.values[hi];
    return a.map((v, i) => v + s * (b[i] - v));
  }
}

function trackOfJointTrajectory(jt, prefix) {
  const names = jt.joint_names.map((j) => (prefix ? `${prefix}/${j}` : j));
  const pts = jt.points || [];
  return new Track(
    names,
    pts.map((p) => p.time_from_start),
    pts.map((p) => p.positions),
  );
}

function untimedTrack(names, waypoints) {
  const times = [0];
  for (let i = 1; i < waypoints.length; i++) {
    let d = 0;
    for (let k = 0; k < waypoints[i].length; k++) {
      d = Math.max(d, Math.abs(waypoints[i][k] - waypoints[i - 1][k]));
    }
    times.push(times[i - 1] + d / UNTIMED_SPEED);
  }
  return new Track(names, times, waypoints);
}

/** Merges tracks of disjoint variables onto the union of their sample times. */
function mergeTracks(tracks) {
  if (tracks.length === 1) return tracks[0];
  const names = tracks.flatMap((t) => t.names);
  const times = [...new Set(tracks.flatMap((t) => t.times))].sort((a, b) => a - b);
  const values = times.map((t) => tracks.flatMap((tr) => tr.at(t)));
  return new Track(names, times, values);
}

/** Robot names and the joint names of each robot in a multi-robot schedule. */
function scheduleJoints(job) {
  const r = job.result;
  const names = r.schedule.robots || [];
  return names.map((robot, i) => {
    const fromResult = (r.robots || []).find((x) => x.name === robot);
    if (fromResult && fromResult.variables) return fromResult.variables;
    const req = (job.request && job.request.trajectories) || [];
    const t = req.find((x) => x.robot === robot) || req[i];
    return t ? t.joints : [];
  });
}

/**
 * The timeline of a plan job: `{track, events, phase, timed, source}`. `events` are
 * `{kind, time, robot, end_effector, object, grasp}` sorted by time; `phase` (multi-robot) is
 * `{robots, path, knots: [{time, phase}]}`.
 */
export function timelineOfJob(job) {
  const r = job.result;
  if (!r) throw new Error(`plan ${job.id} has no result (state: ${job.state})`);
  let track;
  let timed = true;
  let source;
  if (r.trajectory && r.trajectory.points && r.trajectory.points.length) {
    track = trackOfJointTrajectory(r.trajectory, null);
    source = 'trajectory';
  } else if (r.trajectories && Object.keys(r.trajectories).length) {
    track = mergeTracks(
      Object.entries(r.trajectories).map(([robot, jt]) => trackOfJointTrajectory(jt, robot)),
    );
    source = 'trajectories';
  } else if (r.schedule && r.schedule.points && r.schedule.points.length) {
    const robots = r.schedule.robots || [];
    const joints = scheduleJoints(job);
    const names = robots.flatMap((robot, i) => joints[i].map((j) => `${robot}/${j}`));
    track = new Track(
      names,
      r.schedule.points.map((p) => p.time_from_start),
      r.schedule.points.map((p) => p.positions.flat()),
    );
    source = 'schedule';
  } else if (r.variables && r.waypoints && r.waypoints.length) {
    track = untimedTrack(r.variables, r.waypoints);
    timed = false;
    source = 'waypoints';
  } else {
    throw new Error(`plan ${job.id} (${job.kind}) has no path to show`);
  }

  // Event times: `time_from_start` (timed plans), `time` (schedules), else the waypoint's time.
  const waypointTime = (w) => {
    if (r.trajectory && r.trajectory.waypoints && r.trajectory.waypoints[w]) {
      return r.trajectory.waypoints[w].time_from_start;
    }
    if (!timed && track.times[w] !== undefined) return track.times[w];
    return undefined;
  };
  const events = (r.trajectory && r.trajectory.events) || r.events || [];
  const timedEvents = events
    .map((e, order) => {
      let time = e.time_from_start;
      if (time === undefined) time = e.time;
      if (time === undefined && e.waypoint !== undefined) time = waypointTime(e.waypoint);
      return { ...e, time: time === undefined ? 0 : time, order };
    })
    .sort((a, b) => a.time - b.time || a.order - b.order);

  // The phase path: under `result.schedule` (multi_robot plans) or at the top of the result
  // (`schedule` jobs, whose `robots` are the names in phase order).
  let phase = null;
  const sched = r.schedule && r.schedule.phase_path ? r.schedule : r.phase_path ? r : null;
  const phaseRobots = sched ? (sched.robots || []).map((x) => (typeof x === 'string' ? x : x.name)) : [];
  if (sched && phaseRobots.length >= 2) {
    phase = {
      robots: phaseRobots,
      path: sched.phase_path,
      knots: (sched.points || []).map((p) => ({ time: p.time_from_start, phase: p.phase })),
    };
  }
  return { track, events: timedEvents, phase, timed, source };
}

/** Phase vector at time t from the schedule's knots (linear between knots). */
export function phaseAt(phase, t) {
  const tr = new Track(
    [],
    phase.knots.map((k) => k.time),
    phase.knots.map((k) => k.phase),
  );
  return tr.at(t);
}
