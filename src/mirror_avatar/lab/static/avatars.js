// An avatar's player stepped in the page, built from the message the server sends
// (mirror_avatar.browser.browser_arrays): a recording, the tabular cyber player's greedy step or
// the deep cyber player's. Each function repeats its Python twin's arithmetic in the same order
// (named beside it), so the page's positions are the Python player's (METHODS section 16).
// The page holds no number of a model: every array and constant comes in the message.

export const FORMAT = "mirror-avatar/browser-player";
export const VERSION = 1;

// The message's {shape, data} as a typed array (Float64Array unless told), checked against its
// shape.
function array(message, name, Type = Float64Array) {
  const entry = message.arrays[name];
  if (!entry) throw new Error(`${message.label}: the message has no array ${name}`);
  const size = entry.shape.reduce((a, b) => a * b, 1);
  if (entry.data.length !== size) throw new Error(`${message.label}: ${name} is not of its shape`);
  return Type.from(entry.data);
}

// mirror_avatar.dynamics.hkb.hkb_acceleration
function hkbAcceleration(x, v, u, p) {
  return -(p.alpha * x * x + p.beta * v * v - p.gamma) * v - p.omega * p.omega * x + u;
}

// mirror_avatar.dynamics.hkb.clip_to_range
function clipToRange(x, v, range) {
  if (x > range[1]) return [range[1], Math.min(v, 0.0)];
  if (x < range[0]) return [range[0], Math.max(v, 0.0)];
  return [x, v];
}

// mirror_avatar.dynamics.hkb.advance_hkb: u held over one period, RK4 substeps, clipped.
function integrateHkb(x, v, u, p, range) {
  const h = p.period / p.n_substeps;
  for (let s = 0; s < p.n_substeps; s++) {
    const a1 = hkbAcceleration(x, v, u, p);
    const x2 = x + 0.5 * h * v, v2 = v + 0.5 * h * a1;
    const a2 = hkbAcceleration(x2, v2, u, p);
    const x3 = x + 0.5 * h * v2, v3 = v + 0.5 * h * a2;
    const a3 = hkbAcceleration(x3, v3, u, p);
    const x4 = x + h * v3, v4 = v + h * a3;
    const a4 = hkbAcceleration(x4, v4, u, p);
    x += h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4);
    v += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
  }
  return clipToRange(x, v, range);
}

// mirror_avatar.players.base.neighbour_mean: summed in order from the first.
function neighbourMean(values) {
  let total = values[0];
  for (let j = 1; j < values.length; j++) total += values[j];
  return total / values.length;
}

// The index of the largest of n values from offset (the first of equals), as numpy.argmax.
function argmax(values, offset, n) {
  let best = 0;
  for (let a = 1; a < n; a++) if (values[offset + a] > values[offset + best]) best = a;
  return best;
}

// mirror_avatar.learning.discretisation.compute_features
function cellFeatures(features, x, v, xp, vp, r) {
  if (features === "absolute") return [x, v, xp, vp];
  if (features === "relative") return [x - xp, v - vp, xp, vp];
  return [x - xp, v - r, x, r];
}

// mirror_avatar.learning.discretisation.state_index: each feature's bin, row-major.
function stateIndex(values, edges, offsets) {
  let index = 0;
  for (let d = 0; d < values.length; d++) {
    const start = offsets[d], stop = offsets[d + 1];
    let count = 0;
    for (let i = start; i < stop; i++) if (!(values[d] < edges[i])) count++;
    index = index * (stop - start + 1) + count;
  }
  return index;
}

// The tabular policy: mirror_avatar.learning.agent.cyber_step's choice of action.
function tabularPolicy(message) {
  const q = array(message, "q_table"), edges = array(message, "edges");
  const offsets = array(message, "offsets", Int32Array);
  const nActions = message.arrays.q_table.shape[1];
  return (x, v, positions, velocities, r) => {
    let xp = x, vp = v;
    if (positions.length > 0) {
      xp = neighbourMean(positions);
      vp = neighbourMean(velocities);
    }
    const cell = stateIndex(cellFeatures(message.features, x, v, xp, vp, r), edges, offsets);
    return argmax(q, cell * nActions, nActions);
  };
}

// mirror_avatar.deep.features.encode: the network's input vector, written into out.
function encode(layout, x, v, r, positions, velocities, out) {
  out[0] = x * layout.position_scale;
  out[1] = v * layout.velocity_scale;
  let i = 2;
  if (layout.use_reference) out[i++] = r * layout.velocity_scale;
  const m = positions.length;
  let meanX = x, meanV = v;
  if (m > 0) {
    meanX = 0.0;
    meanV = 0.0;
    for (let j = 0; j < m; j++) meanX += positions[j];
    for (let j = 0; j < m; j++) meanV += velocities[j];
    meanX /= m;
    meanV /= m;
  }
  out[i] = (meanX - x) * layout.relative_position_scale;
  out[i + 1] = (meanV - v) * layout.relative_velocity_scale;
  i += 2;
  out.fill(0.0, i);
  if (layout.n_slots === 0 || m === 0) return;
  const relative = Array.from(positions, (p) => p - x);
  const nearest = relative.map((_, j) => j).sort((a, b) => Math.abs(relative[a]) - Math.abs(relative[b]));
  const ordered = nearest.slice(0, layout.n_slots).sort((a, b) => relative[a] - relative[b]);
  const w = layout.slot_width;
  ordered.forEach((j, s) => {
    out[i + w * s] = relative[j] * layout.relative_position_scale;
    out[i + w * s + 1] = (velocities[j] - v) * layout.relative_velocity_scale;
    out[i + w * s + 2] = 1.0;
  });
}

// mirror_avatar.deep.network.q_values: ReLU layers, a linear output, each sum in order. The
// layers' outputs are written into buffers, one per layer (Float64Array), the last returned.
function qValues(weights, sizes, input, buffers) {
  let activation = input, start = 0;
  const last = sizes.length - 2;
  for (let layer = 0; layer <= last; layer++) {
    const fanIn = sizes[layer], fanOut = sizes[layer + 1];
    const out = buffers[layer];
    for (let o = 0; o < fanOut; o++) {
      let total = weights[start + fanIn * fanOut + o];
      const row = start + o * fanIn;
      for (let i = 0; i < fanIn; i++) total += weights[row + i] * activation[i];
      out[o] = layer === last || total > 0.0 ? total : 0.0;
    }
    activation = out;
    start += (fanIn + 1) * fanOut;
  }
  return activation;
}

// The deep policy: mirror_avatar.deep.player.deep_step's choice of action.
function deepPolicy(message) {
  const weights = array(message, "weights"), sizes = array(message, "sizes", Int32Array);
  const input = new Float64Array(sizes[0]);
  const buffers = Array.from(sizes.subarray(1), (width) => new Float64Array(width));
  const nActions = sizes[sizes.length - 1];
  return (x, v, positions, velocities, r) => {
    encode(message.network, x, v, r, positions, velocities, input);
    return argmax(qValues(weights, sizes, input, buffers), 0, nActions);
  };
}

// mirror_avatar.learning.acceleration_player.AccelerationPlayer: the policy picks an
// acceleration, held over the period on the player's own HKB end effector.
function learnedPlayer(message, policy) {
  const actions = array(message, "actions");
  const reference = message.arrays.reference ? array(message, "reference") : null;
  return {
    lastControl: NaN,
    lastReference: NaN,
    reset() {
      this.k = 0;
      this.state = [message.start[0], message.start[1]];
      this.lastControl = this.lastReference = NaN;
      return this.state;
    },
    step(observation) {
      let r = 0.0;
      if (reference) {
        if (this.k >= reference.length) throw new Error(`${message.label}: past its reference`);
        r = this.lastReference = reference[this.k];
      }
      this.k += 1;
      const [x, v] = this.state;
      const u = actions[policy(x, v, observation.positions, observation.velocities, r)];
      this.lastControl = u;
      this.state = integrateHkb(x, v, u, message.dynamics, message.range);
      return this.state;
    },
  };
}

// mirror_avatar.players.recorded.RecordedPlayer: the recording, then its last position at rest.
function recordedPlayer(message) {
  const track = array(message, "track");
  const length = message.arrays.track.shape[1];
  return {
    lastControl: NaN,
    lastReference: NaN,
    reset() {
      this.k = 0;
      return [track[0], track[length]];
    },
    step() {
      const k = this.k++;
      if (k + 1 < length) return [track[k + 1], track[length + k + 1]];
      return [track[length - 1], 0.0];
    },
  };
}

const KINDS = {
  recorded: recordedPlayer,
  cyber: (message) => learnedPlayer(message, tabularPolicy(message)),
  deep: (message) => learnedPlayer(message, deepPolicy(message)),
};

// Build the player a message describes: reset() returns its [position, velocity] at t_0,
// step({positions, velocities}) its [position, velocity] one period later, given its
// neighbours' positions (units) and velocities (units/s) at t_k.
export function makePlayer(message) {
  if (message.format !== FORMAT || message.version !== VERSION) {
    throw new Error(`not a ${FORMAT} message of version ${VERSION}`);
  }
  const make = KINDS[message.kind];
  if (!make) throw new Error(`${message.label}: the page cannot step a ${message.kind} player`);
  return Object.assign(make(message), {
    kind: message.kind, label: message.label, period: message.period,
  });
}
