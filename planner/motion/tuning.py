"""Every tuning value of whole-body motion, named and explained in one place.

Units: metres, seconds, radians; costs are pink's normalised task costs (a cost ``c`` on a
task makes an error ``e`` weigh ``c * e`` in the least squares, so a stance cost 100 times the
COM cost lets the COM pull a contact off by a hundredth of its own error at most).
"""

from __future__ import annotations

import math

# --- control loop -------------------------------------------------------------------------
SUBSTEPS = 2
"""Control steps per keyframe period: at 30 keyframes per second the QP runs at 60 Hz."""

STEP_SUBSTEPS = 1
"""Control steps per keyframe period in a Twister step (a one-step move, ``MotionSpec.substeps``)
outside its fast phases: one, each keyframe's stance then set back on its contacts
(``MotionSpec.hold_stance``, ``WholeBodyTracker.hold_stance``: the QP holds contacts with a
dominant weight, not exactly, and one step per keyframe leaves up to 13 mm of drift), which
takes a quarter off a step's CPU. Plans keep ``SUBSTEPS``, and set back only in their last
resort (2PAC's curve built whole) when it is not clean without: at one step, stairs and
rubble walks lose their landings, and setting back alone changes the climbing wall's trial
builds until its seed + 4 no longer plays."""

HOLD_STANCE_DAMPING = 1e-6
"""Damping (m^2, rad^2) of the least-norm step that sets a keyframe's stance effectors back on
their contacts after its control steps (``WholeBodyTracker.hold_stance``)."""

HOLD_STANCE_ITERATIONS = 3
"""Gauss-Newton steps at most of that setting back (a swing that has just landed may be a few
millimetres and degrees off its contact)."""

HOLD_STANCE_TOLERANCE = 1e-5
"""m or rad: a stance whose contact errors (all components, stacked) are this small in norm is
left as is."""

FAST_SUBSTEPS = 6
"""Control steps per keyframe period in a phase whose COM moves fast (a jump's stances and
flights: 180 Hz at 30 keyframes per second): a step's joint motion is small enough that the
linearised contact constraints hold the stance within a millimetre."""

FAST_COM_SPEED = 1.0
"""m/s: a fast-COM phase (``MotionPhase.fast_com``) runs ``FAST_SUBSTEPS`` only where its COM
curve goes faster than this (a push, a landing); a jump's crouch and stand-up shifts (about
0.5 m/s at most) run ``SUBSTEPS``, as a walk does."""

FAST_COM_SAMPLES = 16
"""Points of a fast-COM phase's curve whose differences give its speed for ``FAST_COM_SPEED``."""

MAX_JOINT_SPEED = 10.0
"""rad/s, cap on every joint's speed on top of the URDF's own velocity limit."""

ROOT_LINEAR_SPEED = 0.8
"""m/s per axis of the root's own frame, outside jumps (at most 1.4 m/s climbing a stair
diagonally, ``MAX_ROOT_SPEED``): a body whose COM follows its curve at walking pace never
needs more, and without a bound the tracker threw the pelvis forward at 2.2 m/s to let a
fast swing leg catch its target."""

ROOT_ANGULAR_SPEED = 4.0
"""rad/s per axis, the root's turning speed outside jumps."""

ROOT_YAW_SPEED = 2.5
"""rad/s, the root's turning speed about its own z axis outside jumps (the trunk's task
leaves its yaw free): at ``ROOT_ANGULAR_SPEED`` the quadruped's trunk snapped from side to
side at 4.3 rad/s to help a foot reach over rubble, where the planned states turn at most 9
degrees; bounded, its heading changes at 2.8 rad/s at most between two keyframes (the bound
is on the trunk's own axis) and HyQ's stance contacts slip less (1.2 mm instead of 2.3 on
hpp_rubbles_4). Not lower: at 1.5 rad/s the humanoid's Twister break of a
foot on the mat slipped its stance foot over 5 mm at brisk timing (the yaw helps it hold)
and fell back to the slow one, 2.7 s instead of 1.35 s."""

FREE_LIMB_ACCELERATION = 20.0
"""rad/s^2, the acceleration bound of a free limb's joints (a limb neither holding a contact
nor swinging: the humanoid's and Talos's arms on a walk) outside jumps, in pink's
``AccelerationLimit`` form: a control step's joint motion differs from the last one's by at
most this times dt^2, and never so fast that the joint could not brake before its position
limit. The COM task may use the free arms (where the legs and trunk cannot keep the COM on a
brisk curve: kept out of it, one stairs_humanoid seed of six failed and a Talos stair seed's
COM lagged 85 mm), but unbounded they swung forward to horizontal and back in 0.15 s
(100 rad/s^2 at the 99th percentile, 4.6 rad/s at most on hpp_stair_bauzil_talos). At 20 the
same arms move at 3.2 rad/s at most, at the pace of a gesture, and every stair seed still
plays (stairs_humanoid's average pace 0.43 m/s instead of 0.47 over six seeds: a brisk window
more is slowed)."""

QP_SOLVER = "daqp"
"""Backend of qpsolvers for the per-step QP (measured: about 0.1 ms for the humanoid)."""

DAMPING = 1e-4
"""Tikhonov weight on the step itself: keeps the QP strictly convex, damps idle dofs."""

# --- task costs -----------------------------------------------------------------------------
STANCE_COST = 100.0
"""Stance contacts: dominant, so the COM and the swing never drag a held contact."""

COM_COST = 40.0
"""Centre of mass following its curve."""

SWING_POSITION_COST = 20.0
"""The swinging effector following its arc."""

SWING_ORIENTATION_COST = 5.0
"""A swinging patch (sole, palm) turning toward its landing orientation (per rad)."""

TRUNK_COST = 4.0
"""Root roll and pitch held at the planned trunk orientation (yaw left free), for a
character whose trunk stays level (``max_pitch`` at most ``LEVEL_TRUNK_PITCH``): at 2 the
COM task rolled HyQ's trunk 25 deg on hpp_darpa_hyq and pitched the humanoid's 21 deg on
the stairs; at 4, 17 and 10 deg."""

PITCHING_TRUNK_COST = 2.0
"""The same for a trunk that pitches with the terrain (the hexapod): held firmer, the
climbing hexapod's trunk could not lean in to keep its feet on the wall (a stance foot
slipped 18-20 mm)."""

TRUNK_HEIGHT_COST = 5.0
"""Root height (along the trunk's own z axis) pulled toward the planned state's: the COM
alone leaves the body free to crouch and fold; the planned states say how tall it stands."""

POSTURE_COST = 1.0
"""Joints pulled toward the phase's planned posture: arms hang naturally, knees unfold."""

FREE_LIMB_POSTURE_COST = 2.0
"""``POSTURE_COST`` of the joints of a free limb (neither holding a contact nor moving, as
``FREE_LIMB_ACCELERATION``): at 1 the COM task raised Talos's free arms 75 deg forward on the
stairs (0.47 rad at the 90th percentile); at 2 they swing 0.6 rad at most, 0.1 at p90."""

TORSO_POSTURE_COST = 5.5
"""``POSTURE_COST`` of the joints of no limb (the chest's, the head's): at 1 the COM task
folded Talos's chest up to 70 deg from the vertical on the stairs while the pelvis kept
its 25 deg bound; at 5.5 the chest leans 30 deg at most, as far as the pelvis under it."""

POSTURE_MAX_ERROR = 0.1
"""rad: each joint's posture target is at most this far from where the joint is (the
posture error saturated like the COM's and the swing's): a posture far from the current one
(the next state's legs) pulled the feet 7 mm off their contacts in the first step."""

LEVEL_TRUNK_PITCH = 0.05
"""rad: a character allowed at most this pitch (``max_pitch``) keeps its trunk level; one
allowed more (the hexapod) aims at the pitch of the planned states."""

SWING_MAX_ERROR = 0.06
"""m: a swing target further than this from the effector is pulled in to this distance, so
that a swing held back by an obstacle never outweighs the stance contacts."""

COM_MAX_ERROR = 0.03
"""m: the same saturation for the COM target."""

TRUNK_GAIN = 0.2
"""The trunk turns toward its target orientation gently (a fifth of the error per step)."""

TASK_GAIN = 1.0
"""Fraction of a task's error corrected per control step (1: dead-beat)."""

POSTURE_GAIN = 0.2
"""The posture converges gently: a low-pass on the free limbs."""

MAX_TILT = math.radians(25.0)
"""rad: a trunk that aims upright (plans, on level ground or stairs) never tilts further
from the vertical than this: a QP inequality, velocity-damper form on the cosine of the
tilt, with the collision dampers (dropped with them if the step has no solution). The
trunk task's pull alone let the humanoid lean back 35 to 41 degrees stepping up stairs on
4 seeds of 20. A jump's flight keeps its trunk as near the landing's trunk axis: the
hexapod pitched 86 degrees mid-air keeping its legs off a ledge."""

MAX_CHEST_TILT = math.radians(30.0)
"""rad: the chest (a humanoid's torso, under its arms) of a trunk that aims upright, its
arms holding no contact, never tilts further from the vertical than this, bounded as the
trunk is (``MAX_TILT``, watched as far under it as the trunk's): with the trunk at its 25
degrees, the posture task alone let the humanoid's chest fold to 41 degrees swinging a foot
0.86 m over a slab of the rubble. A hand on a climbing hold or a handrail leans the chest
as far as it needs (the climbing wall's plans failed with their chests bounded)."""

TILT_WATCH = math.radians(20.0)
"""rad: the tilt bound is a row of the step's QP only beyond this tilt (a trunk well inside
its bound costs nothing)."""

TILT_GAIN = 0.5
"""Share of the margin to ``MAX_TILT`` (in cosine) the trunk may close per control step."""

# --- collision avoidance (velocity damper, Faverjon-Tournassoud form) ---------------------
INFLUENCE_DISTANCE = 0.05
"""m, pairs closer than this get a constraint."""

SECURITY_DISTANCE = 0.005
"""m, the gap a pair may not close below (the damper's d_s)."""

SWING_SECURITY_DISTANCE = -0.004
"""m, d_s of the swinging effector against the scene: it starts and ends on a surface."""

SWING_SECURITY_MARGIN = 0.002
"""m: a swinging effector's shape may go this much deeper than it was at lift-off."""

DAMPER_RATE = 0.5
"""Fraction of the remaining gap (d - d_s) a pair may close in one control step."""

WITNESS_MEMORY = 6
"""Control steps a witness pair is remembered (0.1 s at 60 Hz): coal gives one pair per shape
and step, and a shape by an edge needs the faces on both sides; older half-spaces would fence
the body out of places it has since walked past."""

WITNESS_SUPERSEDE_TOLERANCE = 0.001
"""m: a remembered witness is forgotten when a new one of the same shape sees the scene
locally convex with it (each scene point on or behind the other's plane, to this
tolerance): the new half-space then separates the shape from both features (the same face
seen again, or an edge the shape is moving round). Only a concave pair (a tread and the
riser rising from it) needs both half-spaces. Kept, the tilted half-spaces round the edge
of the next stair held a Talos foot under it for 0.1 s and it landed 0.29 m short."""

MAX_PUSH = 0.01
"""m per control step, the most a constraint may demand to move a pair apart (a shape
already deeper than d_s is pushed out at most this fast)."""

# --- acceptance (the keyframe checker) -----------------------------------------------------
PENETRATION_TOLERANCE = 0.005
"""m, a non-stance link deeper than this inside the scene makes a keyframe collide."""

SELF_PENETRATION_TOLERANCE = 0.005
"""m, two body parts deeper than this into each other make a keyframe collide."""

STATE_SELF_PENETRATION = 0.0025
"""m, two body parts (the URDF's collision shapes) deeper than this into each other make a
contact state invalid (``planner.contact.body.self_collides``): half the keyframe
tolerance, so that the motion into and out of the state has room."""

MAX_DEPTH_CONTACTS = 64
"""Contacts coal reports per shape when a keyframe's shape is inside the scene: the deepest of
them is the shape's depth (the nearest triangle alone understates it)."""

HOLD_TOLERANCE = 0.005
"""m, a stance contact further than this from where it was placed has slipped."""

TRIAL_COM_TOLERANCE = 0.02
"""m, the audit's bound on the keyframe COM's distance to its curve (99th percentile)."""

STEP_COM_TOLERANCE = 0.02
"""m, a Twister step whose keyframe COM strays further than this from its curve (anywhere)
is not clean: the body is not where the balanced COM was planned. Measured on the Twister
games' 20 seeds: 4 of 400 hands-and-feet moves strayed 20 to 118 mm, none elsewhere."""

TRIAL_COM_LAG_SHARE = 0.1
"""A phase of a dynamic trial whose keyframe COM is further than ``TRIAL_COM_TOLERANCE``
from the curve in more than this share of its keyframes is refused (the hexapod's wall at
brisk durations lagged 45-51 mm at the 99th percentile), unless the plan's lagging
keyframes so far stay within ``TRIAL_COM_LAG_BUDGET``."""

TRIAL_COM_LAG_BUDGET = 0.01
"""Share of a plan's keyframes (less one) that may lag their curve by more than
``TRIAL_COM_TOLERANCE`` without refusing the phase they fall in: as many as the audit's 99th
percentile leaves above it. A phase of three to six keyframes (the overlapped swings of a
walker) otherwise failed on a single one: the hexapod's 1 m walk from starts moved 5 mm
lagged 21 mm once in phase 7 of 53, and the whole plan was built again at a slower pace
(twice the computation). Every phase counts, those stopping at rest between phases too
(once exempt): from starts moved 5 mm the humanoid's climbing wall stopped at rest in
phases 40 to 42 lagging 27-31 mm (COM p99 26 mm over 5 seeds), now re-planned there (16 mm)."""

TRIAL_COM_MAX_LAG = 0.08
"""m, a phase of a dynamic trial whose keyframe COM lags further than this once is refused."""

# --- swing ------------------------------------------------------------------------------------
SWING_LIFTS = (0.08, 0.16, 0.24)
"""m, swing arc heights above the chord, tried in turn when the lower one collides or does
not land."""

CLEARING_HEIGHTS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)
"""m: when no arc of ``SWING_LIFTS`` lands cleanly (a ridge right next to the lift-off,
which a symmetric arc clears only far too high), the swing is tracked once more along a
box-shaped path (``clearing_swing_trajectory``): up, across, down, its top this far above
the higher of its two ends (along each end's normal), the lowest of these whose path keeps
the effector ``CLEARING_MARGIN`` off the scene (the highest when none does). On the rubble
(next seed) a foot stepping 17 cm up over a 33 cm ridge 4 cm ahead of it missed its landing
by 24-40 cm at every lift; along the box it landed within 1 mm."""

CLEARING_MARGIN = 0.03
"""m, the gap the swinging effector's shapes keep from the scene along a clearing path (the
tracked effector lags its path and cuts its corners)."""

CLEARING_NORMAL_MARGIN = SECURITY_DISTANCE
"""m, the same gap where a clearing path only rises from its start or descends onto its end
along the normal (the effector lags along its own line and cuts no corner there; the
collision dampers keep it this far): a foot put down on a stair tread beside the riser above
descends past that tread's nosing about 1 cm away."""

CLEARING_END_ZONE = 0.04
"""m: path samples this close to either end (where the effector touches its surface) are not
measured against the scene."""

CLEARING_RISE_SHARE = 0.2
"""Share of a clearing swing before its crossing starts (the rise alone), and after it ends
(the descent alone)."""

CLEARING_SAMPLES = 24
"""Samples of a clearing path measured against the scene."""

MISSED_LANDING_WEIGHT = 30
"""A missed landing (a foot that then slides to its contact) counts as this many colliding
keyframes when attempts are compared."""

LANDING_SETTLE_S = 0.1
"""s: a swing arc reaches its contact this long before its phase ends (at most
``LANDING_SETTLE_SHARE`` of the phase), so the lagging effector has landed when the phase
switches and the contact is held (without it, the first held keyframe jumps up to 7 mm)."""

LANDING_SETTLE_SHARE = 0.2
"""Largest share of a swing phase given to the landing settle."""

SETTLE_COST = STANCE_COST
"""The swinging effector's task cost (position, and orientation of a patch) once its arc has
reached the landing (the settle): the contact it is about to hold, weighted as held. At
``SWING_POSITION_COST`` a hand reaching onto a climbing hold whose forearm met its collision
damper stalled 8-10 mm short (the body had to shift, against the COM's cost), and the stance
task pulled it in at the phase switch in one keyframe, dragging the other hand 5 mm."""

SETTLE_REACH = 0.03
"""m: the settle's cost rises as the effector comes nearer its landing than this (in full at
the landing): a foot held back far above its step that catches up in the settle must not
outweigh the stance contacts (at full cost 23 cm above its landing, it dragged them 7 mm)."""

LANDING_TOLERANCE = 0.02
"""m: a swing whose effector ends further than this from its arc's end has not landed."""

# --- ending in a given state ----------------------------------------------------------------
END_BLEND_S = 0.3
"""s: a motion that must end exactly in a given configuration (a Twister step ends in the
state the contact planner validated) is blended into it over its last this many seconds,
along the configuration manifold with a smoothstep weight; the blended keyframes are
checked again."""

# --- one contact change (a Twister step) ------------------------------------------------------
STEP_MIN_SHIFT_S = 0.3
"""s, shortest phase of a one-step motion without a swing (the COM shift before a break,
the settle after a creation) at speed 1: the motion blends into the validated state over
``END_BLEND_S`` and the contacts must hold meanwhile."""

STEP_CHECKS = 5
"""Samples per phase of the dynamic check (Eq. 1) of a one-step motion."""

STEP_MAX_ACCELERATION = 0.2
"""m/s^2, peak COM acceleration of a one-step motion's rest-to-rest shift at speed 1 on the
slow fallback timing (``MIN_SWING_S``, ``SWING_SPEED``): low enough that the shift over one
foot passes Eq. 1 everywhere (0.4 fails it on the Twister games); ``speed`` squared scales
it."""

STEP_BRISK_ACCELERATIONS = (1.6, 0.8, 0.4)
"""m/s^2, peak COM accelerations tried in turn for a brisk one-step motion (a plan's brisk
durations, ``DYNAMIC_MIN_SWING_S`` and ``DYNAMIC_SWING_SPEED``), the first whose curve
passes Eq. 1 at the checked times kept; ``speed`` squared scales them. Measured on the
Twister games of ``bench/step.py``: steps last 0.6 s instead of 0.9 to 3.3 s."""


# --- timing of a plan (2PAC's sliding window, planner.motion.sequence) -----------------------
SECONDS_PER_METRE = 1.0
"""s per metre of a window's control polygon: the nominal pace of 2PAC's sliding window
(section 6.4.1); ``options.speed`` divides it."""

STEP_DOWN = 0.05
"""m: a limb put at least this much lower than where it left makes a step down, whose state
keeps a plan's COM within ``COM_ABOVE_STATE`` of its own height."""

COM_BELOW_STATES = 0.2
"""m: while a plan's phase holds the contacts of a state, its COM curve and transition points
stay at most this far below the lower of that state's COM and the next state's (the heights
their whole-body postures were found at). The effectors' COM polytopes are hulls of samples
with the limbs anywhere, a foot as high as the hip among them, so they let the COM down to
the feet: the "low" transition cost (2PAC 7.3) walked the humanoid's COM down to the ground
by its fourth step, its feet 19 mm into the floor (APPROXIMATE at every strength). On its
0.6 m walk (seed 7) the COM then crouches 0.24 m at most: SOLVED at 0.25 (slowed to 1.5,
keyframe COM 27 mm off its curve, p99), at 0.2 (slowed to 1.0, 11 mm) and at 0.15 (0.75,
4 mm); the reference plans' curves never come this low."""

COM_ABOVE_STATE = 0.05
"""m: while a plan's phase holds the contacts of a state entered by a step down, its COM curve
and transition points stay at most this far above the COM of that state's own whole-body
posture (on top of the effectors' COM polytopes, 2PAC Eq. 4). The polytopes are hulls of
whole-body samples with arms raised and trunks bent, looser than the body the tracker keeps
upright: walking down stairs, a transition point put the COM 10 cm above the
double-support posture the contact planner found, and the leg stepping down, straight,
landed 20 mm short (half the seeds APPROXIMATE). Not in every state: capped everywhere, the
COM of HyQ on the cinder blocks lagged its curve 77 mm (p99, 14 before) and the climbing
hexapod's windows lost their quasi-static solutions at 3 cm."""

MIN_SWING_S = 0.6
"""s, shortest swing of a plan: a foot or hand leaves, travels and lands."""

SWING_SPEED = 0.8
"""m/s, mean effector speed from lift-off to touch-down: a long reach gets more than
MIN_SWING_S."""

SWING_RISE_FREE = 0.1
"""m of a swing's rise along its contact normal that its timing does not count again
(``spec.swing_length``): a step onto a rock or a kerb."""

SWING_RISE_WEIGHT = 3.0
"""Extra weight of a swing's rise along its contact normal beyond ``SWING_RISE_FREE`` in the
length that times it (``spec.swing_length``). At the straight distance alone, Talos stepping
two treads of the stair_bauzil flight at once (0.54 m on, 0.3 m up) got 0.39 s: its arc met
the tread between, and its foot, held back by its joints' speed limits, landed 25 cm short on
every seed (the plan then re-planned: 0.49 s of computation per animation second, now 0.27).
Counted from the first millimetre at weight 2 instead, the quadruped's steps onto the rubble's
rocks got slower too and 2 of 3 seeds no longer played clean (a shin into a rock); counted
for steps down as well, the humanoid going down the stairs flung its free arms at 90 rad/s^2
(the tracker's acceleration bound yielding in 12 control steps)."""

SWING_DROP_FREE = 0.05
"""m of a swing's drop (its landing below its start along a contact normal) that its timing
does not count again (``spec.swing_length``)."""

SWING_DROP_WEIGHT = 4.0
"""Extra weight of a swing's drop beyond ``SWING_DROP_FREE`` in the length that times it. At
the straight distance alone, the humanoid stepping 15 cm down each stair (0.3 m on) got
0.225 s at the brisk pace: the foot, its knee at the 10 rad/s cap, landed 30 to 45 mm short
at every arc height (0.08 to 0.24 m) and on the box-shaped path, every seed abandoned three
trial builds and re-planned (0.37 s of computation per animation second). Weight 3 (0.3 m
more for a stair) stops just short: three seeds of four slowed phase after phase into an
APPROXIMATE 26 s plan; 3.5 to 6 give clean first trials on six seeds of six (0.13 to 0.18
s per animation second)."""

MIN_SHIFT_S = 0.15
"""s, shortest phase of a plan without a swing (the weight shifts between supports)."""

MAX_WINDOW_STRETCH = 40.0
"""A window of the sliding window is slowed down at most this much to give its phases
their minimum durations (short windows of a slow gait need much: a 0.3 s nominal window
whose swing takes a fifth of it); beyond, which happens when consecutive transition points
(nearly) coincide, that window stops at its transition points (reported per phase as
``rest_to_rest``)."""

MAX_COM_SPEED = 0.5
"""m/s, the COM of a plan never moves faster at speed 1 (``options.speed`` scales it): the
whole-body tracker follows it without the root jumping between keyframes."""

FALLBACK_MAX_ACCELERATION = 0.6
"""m/s^2, peak COM acceleration of the rest-to-rest segments of a window that fell back."""

# --- the dynamic COM of a plan (trajectory.dynamic: Eq. 1 at collocation times) -------------
DYNAMIC_MIN_SWING_S = 0.3
"""s, shortest swing when the COM moves dynamically, before ``DYNAMIC_SLOWDOWNS`` (a brisk
human step swings in about 0.35 s); ``options.speed`` divides it."""

DYNAMIC_SWING_SPEED = 1.2
"""m/s, mean effector speed from lift-off to touch-down of a dynamic plan, before
``DYNAMIC_SLOWDOWNS``: a long reach gets more than ``DYNAMIC_MIN_SWING_S``."""

CHEST_SPEED = 1.0
"""rad/s: the chest's joints turn at most this fast where a plan's chest stands back up to
the reference posture (``generation.stand_up``; the phases on either side of that state
last long enough): a humanoid that climbed with its chest bent 0.9 rad
over the wall let go with its last hand and stood on the top 0.5 s later, still bent 64
degrees (the tracker's chest cannot straighten faster than its posture pull)."""

DYNAMIC_SHIFT_S = 0.1
"""s, a phase without a swing (double support of a walk) in a dynamic plan."""

DYNAMIC_END_S = 0.3
"""s, shortest first and last phase of a dynamic plan: the body starts from rest and comes
to rest (not scaled by ``DYNAMIC_SLOWDOWNS`` nor divided by ``options.speed``)."""

DYNAMIC_SLOWDOWNS = (0.75, 1.0, 1.5)
"""Factors on the durations above, per phase. A plan first tries the first for every phase,
then the next for every phase while the dynamic COM QP finds no curve passing Eq. 1 at
every collocation time. Where the body cannot follow the curve cleanly, the failing phase
and its neighbours (``DYNAMIC_WINDOW_BEFORE``, ``_AFTER``) are slowed to the next factor,
the curve and keyframes before them kept (a fallback per window); beyond the last factor,
the plan keeps 2PAC's quasi-static curve (``com_method`` says which). Measured on seed 1:
the flat humanoid walk plays at 0.75 (0.51 m/s)."""

DYNAMIC_WINDOW_BEFORE = 1
"""Phases before a phase the body could not follow that are slowed with it (the body enters
the failing phase with less speed)."""

DYNAMIC_WINDOW_AFTER = 1
"""Phases after it slowed with it; the curve of the window is found again joined C2 to the
rest, which is kept (later phases shifted in time). When no such window curve passes Eq. 1,
the window reaches to the plan's end."""

REST_SIDE_BEFORE = 3
"""Where slowing a window cannot make it clean, it stops at rest between its phases (2PAC's
fallback) and the dynamic curve is found again on each side to stop there: the one phase
next to it, else up to this many phases before it (or every phase after it)."""

DYNAMIC_SAMPLE_SPACING = 0.015
"""s between the collocation times of a plan's dynamic COM QP
(``trajectory.DynamicSettings.sample_spacing``; 4 at least, 12 at most per phase): a 0.075 s
shift gets 6 instead of 12. Measured on the captured QPs of the humanoid's flat walk, stairs
and climbing wall and the quadruped's rubble (seed 2): 20 to 33 % less time, Eq. 1 valid at 30
times per phase exactly as often as with 12 samples everywhere; at 0.02 s the flat walk's
dropped from 100 to 99.1 %."""

DYNAMIC_SHIFT_SPEED = 1.0
"""m/s: where the dynamic COM QP of a whole plan has no solution at any of
``DYNAMIC_SLOWDOWNS``, it is tried again through them with each phase without a swing
lasting at least the distance between its state's COM and the next state's at this speed.
Rubble, humanoid, seed 15: double supports of 0.1 s in which the contact planner's COM moves
0.34 to 0.44 m (and up 10 cm); at 1 m/s the plan's QP is solved at 1.0. Not the first try: at
1 m/s the flat humanoid walk would take 26 % longer (its shifts move the COM 0.2 to 0.4 m,
which the dynamic curve need not follow)."""

REST_BLAME_SHARE = 0.9
"""Where the dynamic COM QP of a whole plan has no solution at any of ``DYNAMIC_SLOWDOWNS``,
the phases carrying this share of its infeasibility certificate's weight (largest first)
stop at rest between phases and the dynamic curve is found between them. Rubble, humanoid,
seed 15: 94 % of the weight on 7 single-support phases of 63 (39 to 45), the QP of every
other phase feasible."""

REST_BLAME_ROUNDS = 3
"""Rounds of that: a run of phases between the resting ones whose QP is still infeasible
at every level has its own blamed phases stop too, this many times at most before the plan
keeps 2PAC's curve."""

DYNAMIC_MAX_BUILDS = 6
"""Trial builds of dynamic curves before a plan keeps 2PAC's curve, at least (a longer plan
gets ``DYNAMIC_BUILDS_PER_PHASE`` per phase). Each is abandoned at its first unclean phase
and the next resumes from its window, so together they cost about one build of the plan's
keyframes plus the failing windows."""

DYNAMIC_BUILDS_PER_PHASE = 0.15
"""Trial builds per phase of a long plan: the humanoid's climbing wall (127 phases) met an
unclean phase every 2 to 11 phases at brisk durations."""

# --- overlapping swings (planner.motion.overlap) ---------------------------------------------
OVERLAP_LEAD_S = 0.05
"""s the first leg of an overlapped pair swings alone before the second lifts, and the second
alone after the first has landed (one contact change per phase, each in the air at least
one 30 Hz keyframe's worth)."""

OVERLAP_SHIFT_S = 0.05
"""s, the weight shift on every leg before an overlapped pair (``DYNAMIC_SHIFT_S`` elsewhere)."""

OVERLAP_PACES = (0.55, 0.6, 0.75)
"""Factors on the brisk durations of a plan with overlapped swings, tried in turn until the
dynamic COM QP finds a curve and its trial build comes clean (``DYNAMIC_SLOWDOWNS``
elsewhere). Measured on the quadruped's 1.5 m flat walk (phases at least
``OVERLAP_MIN_PERIODS``): 0.56 m/s at 0.5, 0.52 at 0.55, 0.49 at 0.6, 0.42 at 0.75 (one leg
at a time: 0.25), every figure of the audit clean at each; its legs' joints already reach the
10 rad/s cap while they swing at 0.55, which is tried first."""

OVERLAP_MIN_PERIODS = 1.2
"""Keyframe periods each phase of a plan with overlapped swings lasts at least, so that every
phase has a keyframe (the grid's spacing is within a fifth of a period of it once a plan has
three keyframes): at 0.55 times the brisk durations a lead of 0.05 s lasts 0.028 s, less
than a 30 Hz period, and the audit found 14 % of the quadruped walk's phases without one."""

OVERLAP_COM_REACH = 0.12
"""m: a pair of swings is overlapped only where the contacts left while both legs are in the
air pass this close (horizontally) to the COM of the statically balanced states on either
side (a quadruped's diagonal: 3 to 5 cm; its lateral pair, 24 cm, is not overlapped)."""

OVERLAP_MIN_SHARE = 0.5
"""Share of a plan's swings its overlapped pairs must hold for the plan to try them (the try
is of the whole plan, and a failed one is paid for: HyQ's DARPA terrain, rough with level
stretches, and the hexapod's climbing wall found a few level pairs, no clean curve with
them, and 2.7 and 2.3 times the computation)."""

OVERLAP_LEVEL = 0.03
"""m: the contacts of an overlapped pair's states lie within this height of one another."""

OVERLAP_MAX_NORMAL_TILT = math.radians(10.0)
"""rad: and each faces up within this of the vertical (level ground)."""

OVERLAP_ITERATIONS = 10
"""Linearisation rounds of the dynamic COM QP of a plan with overlapped swings, without
generator weight margin: on two diagonal point feet the contact wrench cone is flat (no
torque about the line between them), so a margin on every generator leaves no curve and
the torque's linearisation settles in 5 rounds on the quadruped's flat walk (the default 4
leaves it invalid). The exact check of Eq. 1 at every collocation time still decides."""

OVERLAP_SAMPLE_SPACING = 0.01
"""s between the collocation times of the dynamic COM QP of a plan with overlapped swings
(``trajectory.DynamicSettings.sample_spacing``; 4 at least, 12 at most per phase): its
phases last 0.04 to 0.2 s, and 12 samples in a 0.04 s phase (one every 4 ms) only made the
QP larger. Measured on the captured QPs of HyQ's rubble, the hexapod's and the quadruped's
flat walks (seed 2): 1.62 -> 0.34 s, 0.87 -> 0.47 s and 0.30 -> 0.20 s, Eq. 1 valid at 30
times per phase on 98.3 % (was 99.0 %), 99.6 % and 99.7 % of them."""

MAX_ROOT_SPEED = 1.4
"""m/s, the fastest the root may move between two keyframes of a plan's dynamic motion or a
Twister step (the audit allows 5 cm per 30 Hz keyframe, 1.5 m/s): a body that lags its COM
and then catches up is not played."""

# --- jumps (takeoff push, flight, landing) ----------------------------------------------------
JUMP_ACCELERATION = 2.0 * 9.81
"""m/s^2: the takeoff push accelerates the COM from rest to the takeoff velocity, the landing
decelerates it from the impact velocity to rest, each at a constant acceleration: this one
when the legs reach far enough (the push or landing lasts |v| / a, the COM travels
|v|^2 / 2a; 2 g is a strong human jump), more when they do not (``JUMP_CROUCH_SHARE``): a
short-legged body pushes and lands harder and shorter, never deeper than its reach."""

JUMP_CROUCH_SHARE = 0.3
"""The COM travels at most this share of its standing height above the contacts during a
push or a landing (the legs' reach): a fast jump then pushes or lands harder and shorter."""

JUMP_CROUCH_IK_ITERATIONS = 60
"""Iterations of the whole-body IK that crouches a jump's stance (its COM moved, the
contacts held: ``planner.motion.jump._crouched``)."""

JUMP_CROUCH_TRUNK_WEIGHT = 1.0
"""Weight (in the IK's effector tier, below the COM) of the crouch's trunk keeping the tilt
of its stance (``planner.motion.jump._crouched``): the humanoid's crouches and landings in
the jump scenarios keep their pelvis within 12 degrees of upright (most within one; it
was up to 42 degrees backward), the COM still within 1 mm of its target (the hips fold,
the torso leans forward instead)."""

JUMP_POSTURE_COST = 3.0
"""Cost of the posture pull in a jump's push and landing, whose posture target moves
along the whole-body IK's crouch with the COM (``MotionPhase.posture_from``): pulled only
toward the standing stance (``POSTURE_COST``), the tracker that followed a fast landing COM
with every joint at its speed limit bent the hips backward to their limit and held the
humanoid's COM 40 mm off its curve after it."""

JUMP_TOUCHDOWN_STEP_S = 0.005
"""s: a landing's contacts are made this much later on the parabola at a time, the legs
drawn up further in flight, until the crouched stance's joints at their speed limits move
the COM as fast as it lands (``planner.motion.jump._touchdown``)."""

JUMP_TOUCHDOWN_STEPS = 16
"""Most such steps (80 ms later)."""

JUMP_TOUCHDOWN_SHARE = 0.5
"""The COM may fall at most this share of the landing's reach below the node's before the
contacts are made: the rest is left to the landing."""

JUMP_MIN_STANCE_S = 0.01
"""s: shortest takeoff push or landing (a 180 Hz control step and a half at 30 keyframes per
second). A push the legs' reach would make shorter is reported as out of reach (the body
cannot reach the takeoff velocity); a fast push may fall between two keyframes, the COM curve
and the contacts still say when it happens."""

JUMP_MAX_STANCE_S = 0.6
"""s: longest takeoff push or landing tried when the contact cone refuses the nominal one."""

JUMP_REPLANS = 8
"""Jumps a jump plan refuses at most, one at a time, asking the roadmap again each time: the
roadmap checks the trunk along the parabola, and a jump whose whole-body motion keeps a
colliding or slipping keyframe, or needs a push or landing beyond the legs' reach, is left
out of the next query (``planner.ballistic.planner.plan_jumps``); the cleanest answer found
is the one returned. Over 20 seeds of the gaps scenarios the humanoid needed up to 6, the
hexapod up to 5 (at most 4, one seed of each ended APPROXIMATE)."""

JUMP_SHIFT_ACCELERATION = 1.5
"""m/s^2, peak COM acceleration of the rest-to-rest shifts between jumps (crouching before a
takeoff, standing up after a landing)."""

JUMP_MIN_SHIFT_S = 0.3
"""s: shortest shift between a landing and the next takeoff's crouch."""

FLIGHT_TUCK = 0.4
"""Share of the way mid-flight a carried limb is pulled from its straight path (start offset
to end offset, relative to the COM) toward its natural-posture offset: the legs tuck."""

FLIGHT_TUCKS = ((0.7, 0.1), (0.95, 0.25))
"""(share, extra lift m) of the tuck tried in turn, after ``FLIGHT_TUCK`` and no extra lift,
for a flight whose keyframes collide (a leg trailing into a platform's edge): the carried
limbs pulled further toward their tuck offset, raised this much more (world z)."""

FLIGHT_SETTLE_SHARE = 0.15
"""Share of a flight, at its end, in which the carried limbs hold their landing offsets from
the COM (the legs reach their touchdown posture before the contacts are made, as a swing
settles before its phase ends)."""

FLIGHT_TUCK_LIFT = 0.15
"""m: the natural-posture offset a carried limb tucks toward is raised this much (world z),
so that the feet draw up under the body mid-flight instead of hanging straight."""
