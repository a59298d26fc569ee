// Events of a run (GET /missions/{id}/events, the view frames) in words.

const v = (e) => (e.vehicle_id ? `Vehicle ${e.vehicle_id}` : "A vehicle");
const d = (e) => e.detail || {};

const WORDS = {
  run_started: () => "Run started: launching the vehicles",
  run_running: () => "Every vehicle in GUIDED: flying the plan",
  run_completed: (e) => `Run completed: ${d(e).outcome || "the leader reached the target"}`,
  run_completed_unsafe: (e) => `Run completed UNSAFELY: ${d(e).outcome || ""}`,
  run_aborted: (e) => `Run aborted: ${d(e).outcome || "by the operator"}`,
  run_failed: (e) => `Run FAILED: ${d(e).outcome || ""}`,
  run_interrupted: (e) => `Run INTERRUPTED: ${d(e).outcome || "the service stopped"}`,
  run_resumed: (e) => `Run RESUMED: ${v(e)} leads, leg ${d(e).leg}${(d(e).lost || []).length ? `, lost ${d(e).lost.join(", ")}` : ""}`,
  formation_formed: () => "Formation formed: every wingman at its slot",
  formation_broken: () => "Formation broken",
  loiter_began: (e) => `Loitering round waypoint ${d(e).waypoint + 1} (radius ${d(e).radius_m} m)`,
  waypoint_reached: (e) => `Waypoint ${d(e).waypoint + 1} reached (${d(e).distance_m} m off): leg ${d(e).waypoint + 2} of ${d(e).legs}`,
  avoidance_entered: (e) => `${v(e)} avoiding (inside an influence sphere)`,
  avoidance_left: (e) => `${v(e)} clear again`,
  conflict_resolution_began: (e) => `${v(e)}: conflict with a teammate, vertical resolution`,
  conflict_resolution_ended: (e) => `${v(e)}: conflict resolved`,
  local_minimum_escape: (e) => `${v(e)} escaping a local minimum (s2, pulls up)`,
  vehicle_lost: (e) => `${v(e)} LOST: silent for 5 s of its own time`,
  leader_succeeded: (e) => `${v(e)} LEADS: the leader (vehicle ${d(e).lost_leader}) ${{lost: "was lost", taken_over: "was taken over by another ground station"}[d(e).why] ?? "stopped responding"}`,
  duplicate_system_id: (e) => `${v(e)}: its system id heard on links ${(d(e).links || []).join(", ")} at once (commands on link ${d(e).commanded_link ?? "?"})`,
  vehicle_not_responding: (e) => `${v(e)} NOT RESPONDING (mode ${d(e).mode ?? "?"}, last answer ${d(e).last_ack ?? "none"})`,
  vehicle_responding: (e) => `${v(e)} responding again`,
  vehicle_taken_over: (e) => `${v(e)} TAKEN OVER by ground station ${d(e).by_system ?? "?"} (${d(e).message ?? "?"}): out of the run's command until handed back`,
  vehicle_handed_back: (e) => `${v(e)} handed back: commanded by the run again`,
  safety_violation: (e) => `${v(e)} inside the keep-out of ${d(e).keep_out === "teammate" ? "vehicle" : d(e).keep_out || ""} ${d(e).other ?? ""} by ${d(e).depth_m ?? "?"} m` +
    (d(e).after_end_s !== undefined ? ` (${d(e).after_end_s} s after the end)` : ""),
  takeoff: (e) => `${v(e)} taking off to ${d(e).takeoff_alt_m ?? "?"} m`,
  takeoff_failed: (e) => `${v(e)} takeoff FAILED (height ${d(e).height_m ?? "?"} m)`,
  hold_not_clear: (e) => `${v(e)}: holding circle only ${d(e).clearance_m ?? "?"} m clear of an obstacle`,
  parameter_not_set: (e) => `${v(e)}: parameter ${d(e).name} reads ${d(e).read}, not ${d(e).sent}`,
  parameter_unanswered: (e) => `${v(e)}: parameter ${d(e).name} not answered`,
  lag_over_budget: (e) => `Lag over budget: telemetry ${d(e).telemetry_age_s} s + commands ${d(e).command_delay_s} s = ${d(e).total_s} s (budget ${d(e).budget_s} s)`,
  lag_within_budget: (e) => `Lag within budget again (${d(e).total_s} s of ${d(e).budget_s} s)`,
  tick_overrun: (e) => `Ticks over their period: ${d(e).work_s} s of work in a ${d(e).period_s} s period, ${d(e).measured_hz ?? "?"} Hz of ${d(e).target_hz} (margins widened by the lag)`,
  tick_rate_kept: (e) => `Ticks within their period again: ${d(e).measured_hz ?? "?"} Hz of ${d(e).target_hz} (${d(e).overruns} overran)`,
};

const LEVEL = {
  run_completed: "ok", formation_formed: "ok", vehicle_responding: "ok", waypoint_reached: "ok",
  run_completed_unsafe: "bad", run_aborted: "warn", run_failed: "bad", vehicle_lost: "bad", leader_succeeded: "warn",
  run_interrupted: "bad", duplicate_system_id: "bad", run_resumed: "warn",
  vehicle_not_responding: "bad", safety_violation: "bad", takeoff_failed: "bad",
  vehicle_taken_over: "warn", vehicle_handed_back: "ok",
  formation_broken: "warn", avoidance_entered: "warn", conflict_resolution_began: "warn",
  local_minimum_escape: "warn", hold_not_clear: "warn", parameter_not_set: "warn",
  parameter_unanswered: "warn", lag_over_budget: "warn", tick_overrun: "warn", tick_rate_kept: "ok",
};

export function eventWords(e) {
  const f = WORDS[e.kind];
  if (f) return f(e);
  const detail = e.detail ? ` (${Object.entries(e.detail).map(([k, x]) => `${k} ${x}`).join(", ")})` : "";
  return `${e.vehicle_id ? `Vehicle ${e.vehicle_id}: ` : ""}${e.kind.replaceAll("_", " ")}${detail}`;
}

export function eventLevel(kind) {
  return LEVEL[kind] || "info";
}
