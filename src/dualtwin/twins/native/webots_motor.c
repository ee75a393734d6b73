// Webots' motor law inside MuJoCo's step: the actuator plugin "dualtwin-webots-motor".
//
// An instance drives every actuator that names it (joint transmissions): the twin gives all its motors one
// instance, since MuJoCo's per-instance dispatch (several table look-ups per stage and step) costs more than
// the law; a converted model (motor_plugin.standalone_spec) has one per actuator, each with its motor's
// config. plugin_state holds one block of S_SIZE slots per actuator of the instance, in actuator order.
//
// Per physics step and actuator it does what the Python reference (dualtwin.twins.motors.servo_steps with the
// MuJoCo twin's saturation state machine) does:
//
//   * u, the velocity the motor tracks: 0 without available torque; the target velocity under velocity
//     control; Webots' PID on the position error, clamped to the target velocity, under position control;
//     then the acceleration limit slews u from the previous step's value;
//   * the bounded motor row (ODE's dParamVel u, dParamFMax available): a stiff velocity servo, torque
//     kv (u - qdot), made implicit by adding dt kv to the joint's diagonal of the inertia matrix (backward Euler
//     that the constraint solver sees, like ODE's motor row), while the available torque reaches u under the
//     joint's load (the step's smooth force plus last step's residual); else, saturated, explicitly the torque
//     that takes the joint to u under its load (the residual only while a constraint still acts on the
//     joint), clamped to +-available: exactly the available torque while the load holds;
//   * torque control: the commanded torque.
//
// The load is the step's smooth force on the joint (passive - bias + applied, computed before the actuators)
// plus the residual of the last step (contacts, coupled joints), from its velocity change; while saturated, less
// a constraint force that pushed the joint the way the motor pushes (a reaction, see servo_steps). After the step,
// actuator_force holds the torque the motor applied over it.
//
// Why the inertia matrix and not the model's dof_armature (what the Python twin edits between steps): a
// plugin gets a const model and runs on models shared between simulations (mujoco.batch), so it adds the
// servo's dt kv to the diagonal itself and refactorises. For the sum to be the Python twin's crb + (a + dt kv)
// bit for bit, the twin moves the joint's rotor inertia a from the model (dof_armature 0) into the slot
// S_ARMATURE, which is added with the servo term; a model used elsewhere keeps a in dof_armature, and its
// diagonal is (crb + a) + dt kv, one rounding apart.
//
// The law's state advances once per physics step: compute() (run by every mj_forward, including those
// outside mj_step) writes the step's decisions into "pending" slots, and advance() (run by mj_step only,
// after integration) commits them and applies the post-step saturation check at the new velocity.
//
// Everything lives in plugin_state (so mujoco.batch keeps it per simulation and bit-identical): targets,
// limits, gains, kv and the law's state. reset() fills it from the instance's config; a program that is
// not dualtwin's twin drives the motor through ctrl, interpreted by the config key "ctrl" (position,
// velocity or torque) like Webots' setPosition/setVelocity/setTorque; "none" leaves ctrl unused (the
// twin writes the targets into plugin_state directly).

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <mujoco/mujoco.h>

// plugin_state layout, per actuator (kept in sync with dualtwin/twins/motor_plugin.py)
enum {
  S_TORQUE_MODE = 0,  // 1: torque control
  S_TARGET_POSITION,  // +inf: velocity control
  S_TARGET_VELOCITY,
  S_TORQUE,           // the commanded torque (torque control)
  S_AVAILABLE,        // available torque: the servo's limit
  S_KP,
  S_KI,
  S_KD,
  S_ACCELERATION,     // < 0: unlimited
  S_KV,               // servo stiffness (N m s / rad)
  S_INERTIA,          // the inertia kv was sized for: dt kv = stiffness x inertia
  S_INTEGRAL,         // committed law state
  S_PREVIOUS_ERROR,
  S_U,
  S_RESIDUAL,         // last step's force on the joint besides the motor and the smooth forces
  S_SATURATED,        // 0 servo, +-1 saturated
  S_NEXT_INTEGRAL,    // this step's decisions, committed by advance()
  S_NEXT_PREVIOUS_ERROR,
  S_NEXT_U,
  S_NEXT_SATURATED,
  S_STEP_VELOCITY,    // qdot when the step's servo torque was computed
  S_STEP_SMOOTH,      // the step's smooth force on the joint (passive - bias + applied)
  S_CTRL_MODE,        // 0 none, 1 position, 2 velocity, 3 torque
  S_LAST_CTRL,        // the ctrl value last applied as a command (NaN: none yet)
  S_MAX_VELOCITY,
  S_MAX_TORQUE,
  S_MIN_POSITION,
  S_MAX_POSITION,
  S_GAIN,
  S_ACTUATOR,         // actuator id, joint dof and qpos address (set by reset)
  S_DOF,
  S_QPOS,
  S_LAST,             // 1: the last block of the last instance of this plugin, which refactorises M
  S_ARMATURE,         // rotor inertia added here rather than by the model (see below)
  S_STEP_STIFFNESS,   // the step's servo stiffness: kv, 0 when saturated
  S_STEP_TORQUE,      // the step's explicit torque when saturated (else 0)
  S_REACTION,         // last step's constraint force on the joint (qfrc_constraint), part of the residual
  S_SIZE
};

static const char* kAttributes[] = {"maxVelocity", "maxTorque", "Kp", "Ki", "Kd", "acceleration",
                                    "minPosition", "maxPosition", "stiffness", "ctrl", "multiplier"};
static int kSlot = -1;

static mjtNum config_number(const mjModel* m, int instance, const char* key, mjtNum fallback) {
  const char* text = mj_getPluginConfig(m, instance, key);
  if (!text || !text[0]) return fallback;
  char* end = NULL;
  mjtNum value = strtod(text, &end);
  return end == text ? fallback : value;
}

// The number of actuators driven by ``instance``.
static int actuator_count(const mjModel* m, int instance) {
  int count = 0;
  for (int i = 0; i < m->nu; i++) count += m->actuator_plugin[i] == instance;
  return count;
}

static int motor_nstate(const mjModel* m, int instance) { return S_SIZE * actuator_count(m, instance); }

static int motor_init(const mjModel* m, mjData* d, int instance) {
  int count = 0;
  for (int i = 0; i < m->nu; i++) {
    if (m->actuator_plugin[i] != instance) continue;
    count++;
    if (m->actuator_trntype[i] != mjTRN_JOINT) {
      mju_warning("dualtwin-webots-motor: instance %d drives actuator %d, which has no joint transmission",
                  instance, i);
      return -1;
    }
  }
  if (count == 0 || m->plugin_statenum[instance] != S_SIZE * count) {
    mju_warning("dualtwin-webots-motor: instance %d drives no joint actuator", instance);
    return -1;
  }
  return 0;
}

// One actuator's block of plugin_state from the instance's config.
static void reset_block(const mjModel* m, mjtNum* state, int instance, int actuator, int last) {
  memset(state, 0, sizeof(mjtNum) * S_SIZE);
  int joint = m->actuator_trnid[2 * actuator];
  int dof = m->jnt_dofadr[joint];
  int qpos = m->jnt_qposadr[joint];
  mjtNum max_torque = config_number(m, instance, "maxTorque", 10.0);
  mjtNum stiffness = config_number(m, instance, "stiffness", 100.0);
  state[S_MAX_VELOCITY] = config_number(m, instance, "maxVelocity", 10.0);
  state[S_MAX_TORQUE] = max_torque;
  state[S_KP] = config_number(m, instance, "Kp", 10.0);
  state[S_KI] = config_number(m, instance, "Ki", 0.0);
  state[S_KD] = config_number(m, instance, "Kd", 0.0);
  state[S_ACCELERATION] = config_number(m, instance, "acceleration", -1.0);
  state[S_MIN_POSITION] = config_number(m, instance, "minPosition", 0.0);
  state[S_MAX_POSITION] = config_number(m, instance, "maxPosition", 0.0);
  // The servo stiffness is sized for the joint's inertia (armature included): dt kv = stiffness x M0.
  state[S_INERTIA] = m->dof_M0[dof];
  state[S_KV] = stiffness * m->dof_M0[dof] / m->opt.timestep;
  state[S_GAIN] = config_number(m, instance, "multiplier", 1.0);  // Webots' multiplier scales ctrl
  // Webots' initial state: hold the current (reference) position at up to max velocity.
  state[S_TARGET_POSITION] = m->qpos0[qpos];
  state[S_TARGET_VELOCITY] = state[S_MAX_VELOCITY];
  state[S_AVAILABLE] = max_torque;
  const char* mode = mj_getPluginConfig(m, instance, "ctrl");
  mjtNum ctrl_mode = 0;
  if (mode && !strcmp(mode, "position")) ctrl_mode = 1;
  if (mode && !strcmp(mode, "velocity")) ctrl_mode = 2;
  if (mode && !strcmp(mode, "torque")) ctrl_mode = 3;
  state[S_CTRL_MODE] = ctrl_mode;
  state[S_LAST_CTRL] = NAN;
  state[S_ACTUATOR] = actuator;
  state[S_DOF] = dof;
  state[S_QPOS] = qpos;
  state[S_LAST] = last;
}

static void motor_reset(const mjModel* m, mjtNum* state, void* plugin_data, int instance) {
  int last_instance = 1;
  for (int i = instance + 1; i < m->nplugin; i++) {
    if (m->plugin[i] == kSlot) last_instance = 0;
  }
  int remaining = actuator_count(m, instance);
  for (int i = 0; i < m->nu; i++) {
    if (m->actuator_plugin[i] != instance) continue;
    remaining--;
    reset_block(m, state, instance, i, last_instance && remaining == 0);
    state += S_SIZE;
  }
}

// Whether a constraint row of this step (contact, equality, limit, friction loss) acts on the dof.
static int constrained(const mjModel* m, const mjData* d, int dof) {
  if (mj_isSparse(m)) {
    for (int r = 0; r < d->nefc; r++) {
      const int* column = d->efc_J_colind + d->efc_J_rowadr[r];
      for (int k = 0; k < d->efc_J_rownnz[r]; k++) {
        if (column[k] == dof) return 1;
      }
    }
    return 0;
  }
  for (int r = 0; r < d->nefc; r++) {
    if (d->efc_J[r * m->nv + dof] != 0) return 1;
  }
  return 0;
}

static mjtNum clamp(mjtNum x, mjtNum lo, mjtNum hi) { return x < lo ? lo : (x > hi ? hi : x); }

// Webots' setPosition/setVelocity/setTorque from ctrl, when the config asks for it (as MotorState does).
static void apply_ctrl(mjtNum* s, mjtNum ctrl) {
  if (s[S_CTRL_MODE] == 0 || ctrl == s[S_LAST_CTRL]) return;
  s[S_LAST_CTRL] = ctrl;
  mjtNum value = ctrl * s[S_GAIN];
  if (s[S_CTRL_MODE] == 3) {
    mjtNum limit = mju_min(s[S_AVAILABLE], s[S_MAX_TORQUE]);
    s[S_TORQUE] = clamp(value, -limit, limit);
    s[S_TORQUE_MODE] = 1;
    return;
  }
  if (s[S_CTRL_MODE] == 1) {
    if (s[S_MIN_POSITION] != s[S_MAX_POSITION] && isfinite(value)) {
      value = mju_min(mju_max(value, s[S_MIN_POSITION]), s[S_MAX_POSITION]);
    }
    s[S_TARGET_POSITION] = value;
    s[S_TARGET_VELOCITY] = s[S_MAX_VELOCITY];
  } else {
    s[S_TARGET_POSITION] = INFINITY;
    s[S_TARGET_VELOCITY] = clamp(value, -s[S_MAX_VELOCITY], s[S_MAX_VELOCITY]);
  }
  s[S_TORQUE_MODE] = 0;
  s[S_SATURATED] = 0;
}

// One actuator's law for this step: its force, its term on M's diagonal, its pending state.
static void compute_block(const mjModel* m, mjData* d, mjtNum* s) {
  int actuator = (int)s[S_ACTUATOR];
  int dof = (int)s[S_DOF];
  mjtNum dt = m->opt.timestep;
  apply_ctrl(s, d->ctrl[actuator]);
  mjtNum force;
  mjtNum* diagonal = d->M + m->M_rowadr[dof] + m->M_rownnz[dof] - 1;  // the last entry of the row
  mjtNum integral = s[S_INTEGRAL], previous_error = s[S_PREVIOUS_ERROR];
  mjtNum u = s[S_U];
  mjtNum qdot = d->qvel[dof];
  mjtNum smooth = d->qfrc_passive[dof] - d->qfrc_bias[dof] + d->qfrc_applied[dof];
  s[S_STEP_VELOCITY] = qdot;
  s[S_STEP_SMOOTH] = smooth;
  if (s[S_TORQUE_MODE] != 0) {
    force = s[S_TORQUE];
    *diagonal += s[S_ARMATURE];
  } else {
    // Webots' law (dualtwin.webots.motor_law.motor_velocity), operation for operation.
    mjtNum available = s[S_AVAILABLE], target = s[S_TARGET_POSITION];
    mjtNum next;
    if (available == 0.0) {
      next = 0.0;
    } else if (isinf(target)) {
      next = s[S_TARGET_VELOCITY];
    } else {
      mjtNum error = target - d->qpos[(int)s[S_QPOS]];
      integral = integral + error * dt;
      mjtNum out = s[S_KP] * error + s[S_KI] * integral + s[S_KD] * (error - previous_error) / dt;
      previous_error = error;
      mjtNum limit = fabs(s[S_TARGET_VELOCITY]);
      next = fabs(out) < limit ? out : copysign(limit, out);
    }
    if (s[S_ACCELERATION] >= 0) {
      mjtNum step = s[S_ACCELERATION] * dt;
      next = mju_max(u - step, mju_min(u + step, next));
    }
    u = next;
    // The bounded row, as dualtwin.twins.motors.servo_steps computes it: a servo to u, stiff or saturated.
    mjtNum kv = s[S_KV], inertia = s[S_INERTIA];
    mjtNum reach = dt / inertia, margin = available / kv;
    mjtNum sign = s[S_SATURATED];
    if (sign == 0) {
      // Beyond what the torque reaches under the smooth force: saturated before the step.
      if (u > qdot + ((smooth + available) * reach + margin)) {
        sign = 1.0;
      } else if (u < qdot + ((smooth - available) * reach - margin)) {
        sign = -1.0;
      }
    }
    mjtNum residual = s[S_RESIDUAL], reaction = s[S_REACTION];
    if (sign > 0.0 ? reaction > 0.0 : (sign < 0.0 && reaction < 0.0)) {
      // A constraint's reaction pushing the joint the way the saturated motor pushes (a stop or contact it was
      // driven into, an impact's impulse) holds it only as hard as needed (ODE solves it with the motor row): it
      // does none of the motor's work, only what holds the joint back counts (as servo_steps).
      residual = residual - reaction;
    }
    mjtNum load = smooth + residual;
    if (sign != 0 && !(sign > 0.0 ? u > qdot + ((load + available) * reach + margin)
                                  : u < qdot + ((load - available) * reach - margin))) {
      sign = 0.0;  // within reach under the whole load: the servo reaches u
    }
    s[S_NEXT_SATURATED] = sign;
    mjtNum stiffness = kv, torque = 0.0;
    if (sign != 0) {
      // Saturated: no servo, explicitly the torque that takes the joint to u under its load, within
      // +-available: the smooth force, and last step's residual while a constraint still acts on the joint (a
      // contact that is gone, a released coupling no longer hold it back).
      stiffness = 0.0;
      torque = inertia * (u - qdot) / dt - (constrained(m, d, dof) ? load : smooth);
      torque = torque < available ? torque : available;
      torque = torque > -available ? torque : -available;
    }
    s[S_STEP_STIFFNESS] = stiffness;
    s[S_STEP_TORQUE] = torque;
    force = stiffness * (u - qdot) + torque;
    *diagonal += s[S_ARMATURE] + stiffness * dt;  // the implicit servo (none when saturated)
  }
  s[S_NEXT_INTEGRAL] = integral;
  s[S_NEXT_PREVIOUS_ERROR] = previous_error;
  s[S_NEXT_U] = u;
  d->actuator_force[actuator] = force;
}

static void motor_compute(const mjModel* m, mjData* d, int instance, int capability_bit) {
  mjtNum* s = d->plugin_state + m->plugin_stateadr[instance];
  mjtNum* end = s + m->plugin_statenum[instance];
  for (; s < end; s += S_SIZE) {
    compute_block(m, d, s);
    if (s[S_LAST] != 0) {
      // The last actuator of the last instance: every servo's term is on the diagonal, factorise once.
      mj_factorM(m, d);
    }
  }
}

// Commit one actuator's step: the law's state, the torque the motor applied and the load it met.
static void advance_block(const mjModel* m, mjData* d, mjtNum* s) {
  mjtNum qdot = d->qvel[(int)s[S_DOF]], dt = m->opt.timestep;
  mjtNum torque;
  if (s[S_TORQUE_MODE] != 0) {
    torque = s[S_TORQUE];
  } else {
    s[S_INTEGRAL] = s[S_NEXT_INTEGRAL];
    s[S_PREVIOUS_ERROR] = s[S_NEXT_PREVIOUS_ERROR];
    s[S_U] = s[S_NEXT_U];
    mjtNum sign = s[S_SATURATED] = s[S_NEXT_SATURATED], limit = s[S_AVAILABLE];
    // Saturated: the step's explicit torque; else the backward-Euler servo torque at the step's end velocity.
    torque = s[S_STEP_STIFFNESS] * (s[S_U] - qdot) + s[S_STEP_TORQUE];
    if (sign == 0 && (torque > limit || -torque > limit)) {
      // The stiff servo needed more than the limit (a load it did not foresee): saturated from the next step
      // until u is within reach again.
      s[S_SATURATED] = torque > 0.0 ? 1.0 : -1.0;
    }
  }
  d->actuator_force[(int)s[S_ACTUATOR]] = torque;
  // The joint's damping counts at the step's end velocity (implicitfast), the smooth force had it at the start.
  mjtNum change = qdot - s[S_STEP_VELOCITY];
  s[S_RESIDUAL] = s[S_INERTIA] * change / dt + m->dof_damping[(int)s[S_DOF]] * change - torque - s[S_STEP_SMOOTH];
  s[S_REACTION] = d->qfrc_constraint[(int)s[S_DOF]];
}

static void motor_advance(const mjModel* m, mjData* d, int instance) {
  mjtNum* s = d->plugin_state + m->plugin_stateadr[instance];
  mjtNum* end = s + m->plugin_statenum[instance];
  for (; s < end; s += S_SIZE) advance_block(m, d, s);
}

mjPLUGIN_LIB_INIT(dualtwin_webots_motor) {
  mjpPlugin plugin;
  mjp_defaultPlugin(&plugin);
  plugin.name = "dualtwin-webots-motor";
  plugin.capabilityflags |= mjPLUGIN_ACTUATOR;
  plugin.nattribute = sizeof(kAttributes) / sizeof(kAttributes[0]);
  plugin.attributes = kAttributes;
  plugin.nstate = motor_nstate;
  plugin.init = motor_init;
  plugin.reset = motor_reset;
  plugin.compute = motor_compute;
  plugin.advance = motor_advance;
  kSlot = mjp_registerPlugin(&plugin);
}
