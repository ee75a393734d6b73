"""What the headless Webots twin covers: every Webots node and device, supported / partial / not, and why.

The registry below is data, kept next to the code it describes; ``tests/webots/test_coverage.py`` holds it to
that code (every node the parser knows has exactly one entry; a device marked supported has a controller
class that reads it, one marked "not" has none; a geometry marked supported really creates a collision geom;
every joint type builds an ODE joint) and checks that ``docs/webots-coverage.md`` is this module's rendering.
Regenerate the page with ``python -m dualtwin.webots.coverage``.

Statuses: ``supported`` (Webots' semantics, tested), ``partial`` (works, with the limits given),
``visual`` (parsed and kept in the scene tree for supervisors; nothing to simulate headless; the Camera draws
at most its flat colour),
``not`` (parsed and kept, but without effect: the reason says what is missing).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from dualtwin.webots.api_coverage import api_section

__all__ = ["CATEGORIES", "CONFORMANCE", "REGISTRY", "STATUSES", "Conformance", "Coverage", "main", "render_markdown"]

STATUSES = ("supported", "partial", "visual", "not")
CATEGORIES = {
    "scene": "Scene structure and world",
    "physics": "Physics",
    "geometry": "Geometry (as boundingObject)",
    "joint": "Joints and mechanisms",
    "device": "Devices",
    "visual": "Appearance, lights and view",
}


@dataclass(frozen=True)
class Coverage:
    name: str
    category: str
    status: str
    reason: str
    node: bool = True  # False: a controller-side device without a scene node (Keyboard, Mouse, Joystick)


_NOT_YET_DEVICE = "not yet: enable/disable work, readings are NaN"

REGISTRY: tuple[Coverage, ...] = (
    # -- scene structure and world
    Coverage("WorldInfo", "scene", "partial",
             "basicTimeStep, gravity, ERP/CFM, damping, contactProperties, auto-disable, maxContactJoints "
             "follow Webots; randomSeed seeds sensor noise (same seed, same noise; not Webots' own numbers); "
             "coordinateSystem (ENU/NUE/EUN) sets the gravity direction and the InertialUnit's and GPS's "
             "reference axes; gpsCoordinateSystem WGS84 and gpsReference drive GPS latitude/longitude through "
             "UTM, and gpsReference offsets local GPS readings; a supervisor's edit of gravity (bodies asleep "
             "woken, buoyancy and the Tracks' belt rule following), ERP/CFM, physicsDisableTime and its thresholds (the world and every body) "
             "or basicTimeStep (the next steps that long, the time going on, damping, springs and suspensions "
             "converted again for it) reaches ODE at the next step and a reset restores it; coordinateSystem and "
             "randomSeed are read at load only"),
    Coverage("Solid", "scene", "supported",
             "bodies with mass from Physics/boundingObject, merging and the static basis, kinematic solids "
             "(one that no body or joint carries moves by its linearVelocity/angularVelocity every step, "
             "sensors and getVelocity seeing it; a supervisor's write of them starts, changes or stops that motion, "
             "and on the Solid a body is rooted at sets the body's velocity), supervisor pose/velocity edits (a merged Solid moved takes its new "
             "place in its body, whose mass follows, the root Solid staying put; a static Solid moved, by its "
             "translation/rotation or a Pose above it, Planes included, wakes the bodies asleep where it was and "
             "where it lands); Box/Sphere/Cylinder/Capsule/IndexedFaceSet/Mesh edits (also through "
             "DEF/USE, a PROTO body's DEF that getFromProtoDef reaches with its USEs in that body) resize the ODE geom at the next step, wake bodies around it and reach ray sensors, and "
             "the body's mass, centre of mass and inertia follow the new shape as at load (with a density the "
             "mass follows too, a given mass stays); a "
             "Solid a supervisor imports joins the physics at once by the load's rules (merged into its parent's "
             "body, fixed to the static basis, or in a joint's empty endPoint jointed to the parent where that is "
             "now, the joint's motor and sensor then acting on it; a joint imported inside a Solid that moved since "
             "load is made where the Solid is now, springs included) and remove() takes it out (a joint that loses "
             "its endPoint keeps its devices); a boundingObject a supervisor imports (or a node it imports into "
             "one) becomes geoms at once, on the Solid's body where it is now, and its removal takes them out and "
             "wakes what rested on it; either way the body's mass, centre of mass and inertia are summed again "
             "from it (the Solid stays put, its joints keep their anchors); "
             "edits of a PROTO instance's fields follow its IS links (also through nested and derived PROTOs) "
             "to the expanded nodes (a node imported into or removed from a node-valued interface field, such as an "
             "extension slot, enters or leaves the body's scene tree and physics; a node read through such a field is the "
             "one in the scene, its pose and field writes the physics', and it is saved as it is now), and an interface field bound to "
             "a Solid's translation/rotation or a joint's position reads the physics as that field does, and one bound to another "
             "field reads what changed inside the instance too (a PROTO robot's own setCustomData, its Emitter's setChannel; "
             "worldSave writes it); a field read by a procedural PROTO's template (its own, or one in its body the field "
             "reaches through IS) regenerates the instance (expanded again from its fields and current pose, same handle, DEF and id; a reset restores it), except one "
             "holding a Robot or inside one, which warns and follows the IS links only"),
    Coverage("Robot", "scene", "supported",
             "Python controllers run unchanged, each in its own process (runner), supervisor API, selfCollision "
             "(a supervisor's edit governs the next collision pass), "
             "controllerArgs; synchronization FALSE: the simulation does not wait for that robot's controller (its step "
             "returns once the time it asked for has passed; with no synchronized controller left its steps drive the "
             "simulation); a Robot a supervisor imports at run time starts its controller in its own "
             "process, stepping with the others from the next step, and remove() (or a reset, which takes imported nodes "
             "out) ends it (its step returns -1; a supervisor's remove() of its own Robot acts at the end of its next step, as "
             "Webots); with several controllers the robots are sampled, draw sensor noise "
             "and exchange packets in world order, the supervisors' translation/rotation, joint position and queued "
             "velocity writes of a step are executed in their world order, and so are their other SF field writes (of two "
             "writes of one field in a step the later supervisor's is the value; until a step executes a field write "
             "each supervisor that wrote reads its own value back, the others the value before it, or the pose), a "
             "supervisor's write of a robot's customData "
             "reaches that robot's getCustomData with its next step, two restarts of one robot's controller in a step "
             "leave it one controller, and a simulationReset waits for every controller's step and for the end of the "
             "step that carries it (each then returns at t = 0), so the same world and seed give the same output however the processes are "
             "scheduled; C controllers do not run; battery drained by cpuConsumption and motor consumptionFactor × |torque|; "
             "when it runs out the controller's step returns -1 (it ends) and the motors (Track belts and Propellers too) hold velocity 0 with their "
             "full torque (our reading of Webots' 'stops all motion'); recharged at a Charger"),
    Coverage("Group", "scene", "supported", "children expanded"),
    Coverage("Pose", "scene", "supported",
             "frames of children and bounding objects; a supervisor's translation/rotation edit of one inside "
             "boundingObjects (or of a DEF of it they USE) moves their geoms at the next step, each in its own "
             "Solid's frame, and a body's mass and centre of mass follow (the Solid stays put); among a Solid's "
             "children such an edit moves everything below it at the next step: devices (their readings), lights, "
             "Propellers, the "
             "Shapes that rays and cameras see, merged Solids (their body's mass follows), Solids with bodies "
             "of their own and joints (moved with their subtrees); DEF/USE copies move together"),
    Coverage("Transform", "scene", "partial",
             "scale honoured inside boundingObjects (per axis for Boxes and meshes, the largest factor for round "
             "primitives) and above Solids: the frames below it (Solids, joints' anchors, devices) placed at "
             "scaled translations, boundingObjects scaled, mass x s^3 and inertia x s^5 whatever the Physics "
             "mode, a Propeller's centre of thrust scaled; above a Solid or joint one factor (a non-uniform scale acts as its largest, a non-positive "
             "component is reset to 1, each with a warning); sensor ranges are not scaled. Inside boundingObjects "
             "a supervisor's translation/rotation/scale edit moves and resizes their geoms at the next step as a "
             "Pose's does; among a Solid's children a translation/rotation edit moves what is below it as a "
             "Pose's does (a scale edit there: the Shapes seen by rays and cameras only, not the Solids below, "
             "which keep the load's scale, their own Shapes too, with a warning)"),
    Coverage("Slot", "scene", "supported",
             "its endPoint is placed as a child; a Slot pair as a joint endPoint passes the joint through"),
    Coverage("Billboard", "scene", "visual", "a view-facing group; no physics"),
    Coverage("CadShape", "scene", "visual",
             "its file's meshes (STL, OBJ, COLLADA; ccw) are seen by cameras, their segmentation and recognition "
             "boxes, and by Lidar, RangeFinder and infra-red rays, drawn in grey 0.6 (Assimp's default material: "
             "the file's materials and textures are not read); converted to a visual MuJoCo mesh; no physics (not "
             "a bounding object in Webots either)"),
    Coverage("Charger", "scene", "partial",
             "a Solid and a battery: its energy grows by its charging speed up to its maximum, and it gives the first "
             "robot (world order) whose origin is within radius that robot's recharge speed, at most what it holds "
             "and what the robot's battery lacks (one robot at a time and the order within a step are our reading); "
             "the emissiveColor/gradual colour change is not drawn headless"),
    Coverage("Fluid", "scene", "partial",
             "buoyancy (Archimedes: density x immersed volume x gravity, at the immersed volume's centroid, "
             "before each physics step) on the bodies of Solids whose immersionProperties name it; its "
             "boundingObject must be Boxes (the top face is the surface); no drag, viscosity or streamVelocity "
             "(a world that would need them says so once at load); a Fluid inside a Solid is not simulated; "
             "below a scaled Transform its place and Boxes are scaled"),
    Coverage("ImmersionProperties", "scene", "partial",
             "fluidName selects the Fluid whose buoyancy acts on the Solid: Box bounding objects exactly, Sphere "
             "exactly below the surface (the fluid's side walls are not cut), Cylinder and Capsule through a "
             "24-sided polyhedron of revolution (a capsule: 4 latitude bands per hemisphere) scaled to the true volume, "
             "closed IndexedFaceSet and Mesh bounding objects exactly (any shape, convex or not: signed "
             "tetrahedra clipped by the fluid box; an open mesh encloses nothing and warns once at load); drag "
             "and viscous resistance coefficients are not simulated (a non-zero one warns once at load); read at "
             "every step, so one a supervisor imports or removes, or a Solid given Physics at run time, counts from "
             "the next step (a Fluid imported at run time does not)"),
    # -- physics
    Coverage("Physics", "physics", "supported",
             "density or mass, centerOfMass, inertiaMatrix, damping (volume-weighted over merged solids); a "
             "supervisor's edit of mass, density, centerOfMass or inertiaMatrix (on every USE of the node) sums "
             "the body's mass again by the load's rules (the Solid stays put, its joints are re-anchored where "
             "the centre of mass moved); a Physics node imported into a Solid without one makes it a body by the "
             "load's rules where it is now (its own, merged into its parent's, or jointed as a joint's endPoint), "
             "its removal makes the Solid static where it is; also inside a Robot, whose devices keep working "
             "(a controller's handles, with their commands and sampling, act on and read the new bodies); the "
             "Solids below keep their pose and motion (a jointed child body its velocity and its joint position)"),
    Coverage("Damping", "physics", "supported",
             "linear and angular, converted per step as Webots does; a supervisor's edit of them, or a Damping "
             "node imported into or removed from Physics.damping or WorldInfo.defaultDamping, sets the bodies' "
             "damping again at the next step (both 0 or none: the world's default)"),
    Coverage("ContactProperties", "physics", "partial",
             "material pairs, Coulomb friction, bounce, soft ERP/CFM follow Webots; asymmetric friction (2-4 "
             "values: fdir1 from material1's Box/Plane/Cylinder turned by frictionRotation, mu/mu2 combined with "
             "the angle between both solids' directions; the directions per face are our reading of Webots' "
             "texture mapping); asymmetric slip uses its first value; rollingFriction (rho, rho2, rhoN: ODE's rolling rows; "
             "mu2 stays 0 as Webots leaves it, so rho2/rhoN make the second friction direction frictionless) and "
             "forceDependentSlip as Webots fills ODE's contact; a supervisor's edit of a ContactProperties field or of a "
             "Solid's contactMaterial, and a ContactProperties node imported into or removed from WorldInfo's list, "
             "govern the contacts of the next collision pass"),
    # -- geometry
    Coverage("Box", "geometry", "supported", "ODE box"),
    Coverage("Sphere", "geometry", "supported", "ODE sphere"),
    Coverage("Capsule", "geometry", "supported", "ODE capsule"),
    Coverage("Cylinder", "geometry", "supported", "ODE cylinder (upstream 0.16 contacts may differ from the fork)"),
    Coverage("Plane", "geometry", "supported", "static infinite plane (a Plane on a body stays static)"),
    Coverage("IndexedFaceSet", "geometry", "supported", "ODE triangle mesh of its faces, each cut into "
             "triangles that cover it (a concave face too), as the rays and the camera see it"),
    Coverage("ElevationGrid", "geometry", "partial", "static height field (in a scaled Transform: spacings by the "
             "scale's x and y, heights by its z), rebuilt when a supervisor edits its fields (heights, spacings, "
             "thickness); on a dynamic body it stays static"),
    Coverage("Mesh", "geometry", "supported",
             "ODE triangle mesh of the file's triangles, as an IndexedFaceSet (contacts, ray sensors, touch "
             "sensors; inside Pose/Transform/Group/Shape, Transform scale per axis); mass by dMassSetTrimesh at "
             "the Physics density or mass, centre of mass at the volume's centroid. Files: STL (binary, ASCII), "
             "OBJ, COLLADA (.dae: node transforms and unit applied, up_axis not); every mesh of the file merged, "
             "filtered by name and materialIndex, ccw FALSE reverses the winding. url: http(s) and webots:// "
             "(from $WEBOTS_HOME, else the PROTO cache; `dualtwin webots fetch` fills it), or relative to the "
             "world or PROTO file that writes the node and confined to its project folder (absolute paths and "
             "urls leaving the project are refused). A file that cannot be read, selects no triangle or encloses "
             "no volume: no geom and Webots' fallback 1 kg with an identity inertia, with one warning naming the "
             "node. A supervisor's edit of url, name, materialIndex or ccw builds the geom again at the next "
             "step and the body's mass follows. As a Shape's geometry: drawn by cameras in the Shape's colour "
             "(image, segmentation, recognition boxes) and hit by Lidar, RangeFinder and infra-red rays. ASCII STL "
             "and OBJ coordinates are read as doubles where Webots' Assimp reads floats (a relative difference "
             "below 1e-7). The converter makes MuJoCo meshes of them (a boundingObject collides through its convex "
             "hull there)"),
    Coverage("Cone", "geometry", "visual", "not a bounding geometry in Webots either (ignored with a warning)"),
    Coverage("IndexedLineSet", "geometry", "visual", "lines; no collision in Webots"),
    Coverage("PointSet", "geometry", "visual", "points; no collision in Webots"),
    Coverage("Coordinate", "geometry", "supported", "vertices of IndexedFaceSet"),
    Coverage("Normal", "geometry", "visual", "shading normals"),
    Coverage("TextureCoordinate", "geometry", "visual", "texture mapping"),
    # -- joints and mechanisms
    Coverage("HingeJoint", "joint", "partial",
             "position, stops (stopERP/stopCFM edited at run time reach ODE; at load ODE's world defaults), springs, "
             "dampers, static friction; no suspension (an ODE-fork-only API); a stop at ±π (maxStop or -minStop of "
             "π or more, clamped) holds a driven joint as with the fork, which unwraps the angle where upstream ODE "
             "wraps it: ODE's zero follows a hinge with stops (set again on its own axis when it has turned π/2 "
             "from it), its stops and spring rest shifted by as much"),
    Coverage("SliderJoint", "joint", "supported", "stops; springs emulated with an equivalent LMotor row"),
    Coverage("Hinge2Joint", "joint", "partial",
             "both axes' motors, sensors (continuous multi-turn positions on both axes, read with ODE's own "
             "sign per axis), springs and dampers (a stop AMotor per axis; run-time edits reach ODE), "
             "suspension along the first axis (ODE's hinge2 suspension ERP/CFM, also edited at run time); stops on "
             "both axes (upstream ODE never limits the second, so a stop AMotor holds it); a position edited on "
             "either axis teleports the endPoint, the second axis turned by the first; a Hinge2Joint whose parent has no body gets "
             "no ODE joint and is kinematic: its motors turn the endPoint, body included, which is held on the "
             "joint's pose at rest after every step (what gravity or contacts do to it in Webots is not "
             "documented)"),
    Coverage("BallJoint", "joint", "partial",
             "three axes (the first from jointParameters2, the third from jointParameters3, the second their "
             "cross product; first and third aligned or zero: x and z, with a warning) with motors, position sensors, brakes, stops and friction on an Euler AMotor; "
             "springs, dampers and brakes on a second Euler AMotor; on a static parent both AMotors hang on the "
             "endPoint alone (ODE's first and third axes swapped), so motors, stops, torques and springs act on "
             "each axis as with a body as parent; a position edited on any axis teleports the endPoint (the three "
             "rotations in chain, the other axes kept); kinematic when the endPoint has no Physics"),
    Coverage("JointParameters", "joint", "supported",
             "slider axis, position, stops, spring, damping, friction; edited by a supervisor, position teleports "
             "the endPoint (its subtree's physics reset, motor targets kept) and minStop/maxStop, springConstant, "
             "dampingConstant, staticFriction and axis act from the next step, on every joint and axis (an axis edit "
             "places the endPoint at its position about the new axis, the joint set again there with its position "
             "read on, stops, springs and motor about the new axis; a zero axis is refused with a warning); "
             "imported by a supervisor into a joint's empty "
             "jointParameters field (any axis) they act from the next step, the joint set again where its Solids "
             "are (nothing moves, the current configuration reads the node's position); removed, the joint goes "
             "back to the defaults where it is, its position read on without a jump; a reset puts the joint back "
             "as at load"),
    Coverage("HingeJointParameters", "joint", "supported",
             "axis, anchor and the JointParameters fields (also imported or removed at run time, as JointParameters; "
             "axis and anchor edited at run time act from the next step, the endPoint placed at its position about "
             "the new axis through the new anchor, as JointParameters' axis; suspensionAxis acts on nothing: the "
             "HingeJoint's suspension is not modelled and the Hinge2Joint's lies along its first axis)"),
    Coverage("BallJointParameters", "joint", "supported",
             "anchor (edited at run time: the endPoint turned about the new anchor, the joint set again there)"),
    Coverage("SolidReference", "joint", "partial",
             "closed loops: an ODE joint from the upper body to the named Solid (searched in the joint's "
             "robot, as Webots does) or to the static environment, built after the other joints; one a "
             "supervisor imports into a joint's empty endPoint closes the loop at once, its removal opens it; not "
             "for Hinge2Joint, and a referenced Solid without Physics is ignored"),
    Coverage("Track", "joint", "partial",
             "belt motion through ODE contact surface velocity (Webots' per-contact sign rule), its LinearMotor "
             "(a Motor: position/velocity/force control, with the Motor API's checks, clipping and raw echoes of a "
             "joint motor; no force feedback, no energy use; its fields edited at run time act as a joint motor's), "
             "PositionSensor and Brake (damping the belt in force "
             "control) are devices; a Track without a body does not move; no texture or geometry animation"),
    Coverage("TrackWheel", "joint", "visual",
             "wheels of a Track are turned only visually in Webots; its children are placed at (position.x, 0, "
             "position.y) in the Track's frame (so cameras and range sensors see them there), not turned"),
    Coverage("Propeller", "joint", "partial",
             "thrust and torque from its constants and the motor's kinematic speed, applied to the body carrying "
             "its closest upper Solid (for a Solid without Physics, its nearest ancestor's) at the centre of thrust; "
             "its motor is a device (a Motor) with the Motor API's checks, clipping and "
             "raw echoes of a joint motor (available torque at most maxTorque; no torque feedback); a "
             "supervisor's edit of shaftAxis, centerOfThrust, thrustConstants, torqueConstants or of the motor's "
             "fields acts from the next step; without "
             "Physics above it, a warning and no effect; the helices "
             "are not simulated and a "
             "PositionSensor on it is not exposed"),
    Coverage("Muscle", "joint", "visual", "a visual muscle shape"),
    # -- devices
    Coverage("RotationalMotor", "device", "partial",
             "velocity, position (Webots' PID) and torque control with limits, acceleration and the initial "
             "hold, basic step by basic step as Webots' law gives it (a command before step call k acts from the "
             "first basic step of call k, the law reads the joint position of the previous basic step's end; "
             "checked by hand for controller steps of one and two basic steps in both controller isolation "
             "modes); on a kinematic joint (endPoint without Physics) the motor moves the endPoint itself, its "
             "speed ramping by the acceleration or, when that is -1 or larger, by the available torque (Webots' "
             "kinematic controller); a supervisor's write of its acceleration field sets its acceleration as "
             "setAcceleration does, and simulationReset restores the loaded one; a supervisor's edit of "
             "maxVelocity, maxTorque/maxForce, controlPID (the error integral starts again), minPosition/"
             "maxPosition (a target left outside is clipped into them) or multiplier acts from the next step, and "
             "the getters follow from that step, not before it; a command made in the step of the write uses the "
             "configuration before it, whichever controller made it first (not harmonised again across coupled motors), simulationReset puts the load "
             "configuration back; coupled motors ('name::suffix') relay setPosition/setVelocity/setForce with their "
             "multipliers and their limits are harmonised at load to the first motor's (getTargetPosition and "
             "getVelocity echo the raw value given to the motor itself, the multiplied one for its siblings, as "
             "libController caches them); as in libController, a "
             "negative velocity in position control and a negative acceleration other than -1 are refused with "
             "an error, and a force/torque beyond the available one is clipped with a warning (silently for "
             "coupled motors); torque/force feedback "
             "from ODE's joint feedback: what the joint applies to the endPoint about the anchor along the "
             "axis, in the sense setTorque/setForce would command (hinge, both Hinge2 axes, slider, also on a "
             "static base; the "
             "commanded value in torque control); the motor rows keep the world CFM (Webots' sign and CFM for "
             "these are not confirmed against Webots)"),
    Coverage("LinearMotor", "device", "partial", "as RotationalMotor"),
    Coverage("PositionSensor", "device", "supported",
             "sampled joint position with noise and resolution (edited at run time: from the next sample; a read while disabled prints Webots' error and "
             "returns the last sample, as every sensor's); a motor, position sensor or brake a supervisor "
             "imports into a joint's device field joins its robot's devices (getDevice, getNumberOfDevices, in "
             "scene-tree order for getDeviceByIndex) and acts on the axis from the next step (a motor holding the "
             "joint where it is, §5.1), also for controllers in their own processes; removed, it leaves the "
             "device list and its effect ends (a motor lets its axis go, a brake's damping leaves it); one device "
             "of each kind per axis, a second one is ignored with a warning"),
    Coverage("Brake", "device", "supported",
             "setDampingConstant adds to the axis' dampingConstant through the implicit damper row, from the "
             "next step; linked from its Motor and PositionSensor"),
    Coverage("GPS", "device", "supported",
             "position of the device origin (world axes offset by gpsReference, or WGS84 "
             "latitude/longitude/altitude through UTM around gpsReference), accuracy noise, resolution; speed and speed vector from the displacement over the "
             "last basic step (speedResolution); NaN until the first sample; noiseCorrelation and speedNoise "
             "are not applied"),
    Coverage("Gyro", "device", "supported",
             "angular velocity of the carrying body in the device frame, per-axis lookup table (noise), "
             "resolution (both also edited at run time, from the next sample), disabled axes read NaN"),
    Coverage("Accelerometer", "device", "supported",
             "proper acceleration of the device origin as a point of its body (lever-arm centripetal and "
             "tangential terms), change of point velocity over the last basic step minus gravity, in the "
             "device frame; per-axis lookup table (noise), resolution (both also edited at run time, from the next "
             "sample), disabled axes read NaN"),
    Coverage("InertialUnit", "device", "supported",
             "roll/pitch/yaw and quaternion of the device frame in the world's reference frame (ENU as is; "
             "NUE/EUN read with their up axis as z, so a turn about the vertical is a yaw), resolution, "
             "disabled axes read NaN; noise relative to each angle's half-range (noise·π on roll and yaw, "
             "noise·π/2 on pitch, drawn per sample), the quaternion from the noisy angles"),
    Coverage("DistanceSensor", "device", "partial",
             "generic, sonar and laser as Webots: rays against bounding objects (own robot excluded unless "
             "selfCollision), ray layout and Gaussian weights, sonar echo angle, lookup table with noise, "
             "resolution, sampled at the basic step where the period elapses from the poses after that "
             "step's physics (sensor, targets), so rays follow a driving robot and see a falling target where "
             "it is; infra-red rays hit the visual Shapes (own robot included except a Shape enclosing the "
             "sensor, judged in that Shape's own frame; transparent ones skipped), weighted by the reflection "
             "factor of the hit Shape's red (Material diffuseColor or PBR baseColor and roughness; no "
             "textures; a CadShape's default grey) and redColorSensitivity; a Mesh Shape or CadShape is hit on its "
             "file's triangles; a supervisor's edit of lookupTable, numberOfRays, aperture, gaussianWidth, type or "
             "resolution acts from the next sample and the getters follow"),
    Coverage("Compass", "device", "supported",
             "north of WorldInfo.coordinateSystem (+y ENU, +x NUE, +z EUN) in the device frame, per-axis "
             "lookupTable and resolution"),
    Coverage("Altimeter", "device", "supported",
             "coordinate along the world's up axis, Gaussian accuracy noise, resolution"),
    Coverage("TouchSensor", "device", "supported",
             "bumper from contacts of its bounding object in any step since the last sample; force and "
             "force-3d from the feedback of the joint holding its own body (its fixed joint, or the joint whose "
             "endPoint it is), with lookup table and resolution (edited at run time: from the next sample; the type "
             "stays that of the load)"),
    Coverage("Lidar", "device", "partial",
             "one ray per pixel against the visual Shapes (as Webots renders them): layers, fov, tilt, "
             "cylindrical (Euclidean) or planar (depth) ranges, +inf outside [minRange, maxRange), noise, "
             "resolution, point cloud; a rotating lidar's image spans 2π and is filled column by column as its "
             "head turns by −2π·frequency·dt per basic step (sampled every basic step, setFrequency within "
             "[minFrequency, maxFrequency]), its rotatingHead Solid turned about its z axis while the lidar is "
             "enabled (seen by cameras and rays, put back by a reset, still after a controller restart until the "
             "new controller enables the lidar); Mesh Shapes and CadShapes "
             "are hit on their files' triangles; Webots' load-time layer check (numberOfLayers at most "
             "verticalFieldOfView·horizontalResolution/fieldOfView, 2π for a rotating one: else rewritten, with "
             "a warning); a supervisor's edit of fieldOfView, verticalFieldOfView, tiltAngle, projection, "
             "minRange, maxRange, near, noise or resolution sets the next scan and the getters; one of "
             "horizontalResolution or numberOfLayers sizes the next scan (the load's layer check applied again), "
             "minFrequency/maxFrequency set setFrequency's bounds (the frequency clamped into them) and "
             "defaultFrequency the frequency; a type edit is not applied (a warning line)"),
    Coverage("RangeFinder", "device", "partial",
             "planar depth image as one ray per pixel against the visual Shapes (as Webots renders them); "
             "+inf outside [minRange, maxRange), noise, resolution (fieldOfView, ranges, noise and resolution "
             "edited at run time set the next image, as width and height its size); no lens, motion blur or saveImage; Mesh Shapes "
             "and CadShapes are hit on their files' triangles"),
    Coverage("Camera", "device", "partial",
             "planar BGRA image of the world's Shapes in their flat colours, drawn headless by the MuJoCo "
             "renderer from the camera's frame: width, height, fieldOfView, near, far, noise, antiAliasing, "
             "sampling, getImageArray, imageGet*, saveImage (PNG/JPEG); the sky in the Background's first "
             "skyColor; no textures (a textured Background shows its skyColor), "
             "exposure, lens, motion blur or spherical/cylindrical projection (drawn planar); the scene is "
             "drawn again after a supervisor changed it (nodes imported or removed, a Pose moved; its own "
             "fieldOfView, near, far, noise, exposure, width or height edited: the next image and the getters); "
             "a Mesh Shape is "
             "drawn from its file's triangles in its appearance's colour, a CadShape in grey 0.6 (materials "
             "of mesh files are not read); a mesh file that cannot be read is not drawn"),
    Coverage("Recognition", "device", "partial",
             "Camera.getRecognitionObjects(): the Solids with recognitionColors in the camera's frustum (near "
             "plane, horizontal fieldOfView, image aspect) within maxRange, nearest first, at most maxObjects, "
             "sampled by recognitionEnable() from the poses after the physics step; id (getFromId resolves it), "
             "position and axis-angle orientation in the camera frame, size along the camera's y and z, "
             "position_on_image/size_on_image from the pinhole projection clipped to the image, colors, "
             "model; segmentation image (BGRA, each pixel of a recognisable Solid in its first colour, black "
             "elsewhere) from MuJoCo's segmentation pass. Our reading, not Webots' text: the object is the "
             "Solid with its subtree and its box is around their bounding objects (else their Shapes); "
             "occlusion 1 and 2 both cast one ray to that box's centre against bounding objects (Webots' ray "
             "rules: the camera's robot does not hide); the camera's Solid and the Solids it is mounted on "
             "are never reported, other parts of its robot are; a Solid without colours is painted in the "
             "nearest colours above it; frameColor and frameThickness draw nothing headless; its fields are read at "
             "every sample, so a supervisor's edit acts from the next one"),
    Coverage("Lens", "device", "not", "not yet (Camera)"),
    Coverage("LensFlare", "device", "not", "not yet (Camera)"),
    Coverage("Focus", "device", "not", "not yet (Camera)"),
    Coverage("Zoom", "device", "not", "not yet (Camera)"),
    Coverage("Radar", "device", "partial",
             "targets: Solids with radarCrossSection whose bounding box overlaps the field of view, in range; "
             "distance, radar-equation power, radial speed, azimuth, occlusion ray, noise, from the poses after "
             "the physics step; cellDistance and cellSpeed are not modelled"),
    Coverage("LightSensor", "device", "supported",
             "irradiance of Directional/Point/SpotLights (attenuation, radius, linear spot fall-off, cos θ, "
             "ambient; a DirectionalLight's direction is global wherever it sits; lights inside Solids at the "
             "Solid's pose; an LED's lights follow the LED), colorFilter averaged over RGB, occlusion rays (the "
             "Solid carrying the light does not hide it), lookupTable and resolution, from the poses after the "
             "physics step"),
    Coverage("Emitter", "device", "partial",
             "in-process channels: channel filters, range and maxRange, medium type, buffer size, baud rate, "
             "infra-red line of sight and aperture, judged from the poses after the physics step of the "
             "packet's arrival; packets of one step reach a receiver in world order (robot, then device), "
             "whichever controller sent first; simulationReset clears the queues; setChannel and setRange write "
             "the channel and range fields; a supervisor's edit of a field (channel, range, maxRange, aperture, "
             "baudRate, bufferSize...) acts from the next step and the getters follow"),
    Coverage("Receiver", "device", "partial",
             "queue, channel filter, buffer size, signal strength 1/d² with noise, emitter direction with noise; "
             "setChannel writes the channel field; fields edited at run time act from the next step, as the "
             "Emitter's; no physics-plugin copy of channel 0"),
    Coverage("Display", "device", "partial",
             "RGBA frame buffer: colour, alpha, opacity, pixels, lines, rectangles, ovals, polygons, image "
             "new/copy/paste/save (PNG)/load/delete; text is not rasterised and attachCamera shows nothing; its width "
             "and height are the load's (a supervisor's edit of them is not applied)"),
    Coverage("Speaker", "device", "not", "not yet: no sound"),
    Coverage("LED", "device", "supported",
             "set/get with colour index or gradual RGB; the lights among its children follow it in Camera images "
             "and LightSensor readings from the next step (off at 0 and at start, else on in the LED's colour); "
             "its Shapes' colour does not change"),
    Coverage("Pen", "device", "partial",
             "write/setInkColor keep their state; ink is visual only in Webots and is not drawn headless"),
    Coverage("Connector", "device", "partial",
             "presence with model/type and distance/axis/rotation tolerances, lock/unlock (unilateral), "
             "autoLock, isLocked at load, ODE fixed joint, snap (the carrying body moves), tensile/shear "
             "breaking with the locked sides' strengths summed; a supervisor's write of a field acts from the next "
             "step (of isLocked: as lock()/unlock()); in Webots' connector_detach test the pair "
             "separates at 0.448 s instead of 0.736 s: the fixed joint carries a third of the pull (the floor "
             "contacts the rest), then ODE's cylinder-plane collider (double precision) drops from 4 contact points "
             "to 1 once the pulled robot tilts by 4.5e-4 rad (1 - cos(tilt) > 1e-7), at a pull of about 1 N; the 32 ms "
             "step then tips the light robot about 0.3 rad in one step and the joint force turns erratic (every "
             "strength rule tried gives 0.448 or 0.608 s; with the pull split we measure, no rule gives 0.736 s)"),
    Coverage("VacuumGripper", "device", "supported",
             "turnOn/turnOff, isOn at load, grasps a body touching its boundingObject with >= contactPoints "
             "points (fixed joint), tensile/shear breaking, presence; a supervisor's write of a field acts from the "
             "next step (of isOn: as turnOn()/turnOff())"),
    Coverage("Keyboard", "device", "supported",
             "headless getKey() is -1 (and an error line at each read while disabled); 'webots run --keys FILE' "
             "replays scripted presses", node=False),
    Coverage("Mouse", "device", "not", "not yet: no pointer headless", node=False),
    Coverage("Joystick", "device", "not", "not yet", node=False),
    # -- appearance, lights and view
    Coverage("Shape", "visual", "supported",
             "its geometry is a collision shape inside boundingObjects; Camera images draw Box, Sphere, "
             "Cylinder, Capsule, Plane and IndexedFaceSet shapes"),
    Coverage("Appearance", "visual", "visual", "only its colour and transparency reach Camera images"),
    Coverage("PBRAppearance", "visual", "visual", "only its colour and transparency reach Camera images (and its red the infra-red rays); a supervisor's edit of its colour, transparency and roughness shows from the next image or sample, on its DEF/USE copies too"),
    Coverage("Material", "visual", "visual", "only its colour and transparency reach Camera images (and its red the infra-red rays); a supervisor's edit of its colour and transparency shows from the next image or sample, on its DEF/USE copies too"),
    Coverage("ImageTexture", "visual", "visual", "not rendered; never downloaded"),
    Coverage("TextureTransform", "visual", "visual", "not rendered"),
    Coverage("Color", "visual", "visual", "not rendered"),
    Coverage("Background", "visual", "visual", "Camera images show its first skyColor behind the Shapes, "
             "rounded to the nearest byte; its cube-map textures are not drawn (a warning); luminosity is not "
             "used"),
    Coverage("DirectionalLight", "visual", "visual",
             "lights Camera images wherever it sits, its direction global (no shadows); on, color, intensities "
             "and direction edited show from the next step's image, an LED's state for an LED's light"),
    Coverage("PointLight", "visual", "visual",
             "lights Camera images (an OpenGL point light, with its attenuation; no shadows); inside a Solid it "
             "moves with it; on, color, intensities, location and attenuation edited show from the next step's "
             "image (and LightSensor sample; a DEF'd light's edit reaches its USEs), an LED's state for an LED's "
             "light"),
    Coverage("SpotLight", "visual", "visual",
             "lights Camera images (cone of cutOffAngle, MuJoCo's fall-off rather than beamWidth; no shadows); "
             "inside a Solid it moves with it; on, color, intensities, location, direction, attenuation and "
             "cutOffAngle edited show from the next step's image, an LED's state for an LED's light"),
    Coverage("Fog", "visual", "visual", "not rendered"),
    Coverage("Viewpoint", "visual", "visual", "no viewer headless"),
)


@dataclass(frozen=True)
class Conformance:
    """A measured result of Webots' own physics regression tests (see :data:`CONFORMANCE`)."""

    tests: tuple[int, int]  # (passed, total)
    checks: tuple[int, int]
    failing: tuple[str, ...]  # the checks that fail, each with what was measured


#: Webots' physics regression tests (``tests/physics`` in its repository), the half kept beside this project as
#: a conformance target (``../shared/conformance/webots-physics``: Webots' worlds with Python checks of the same
#: expected values, run by its ``run.sh`` with this project's ``dualtwin``). Restated here because the product
#: does not ship that suite; ``tests/webots/test_conformance_shared.py`` runs every test of it in ``make test``,
#: one item each, and holds these figures to its list of known failures and to the suite's own table.
CONFORMANCE = Conformance(
    tests=(14, 15), checks=(223, 224),
    failing=("connector_detach, check 2: the locked connectors separate at 0.448 s, not at Webots' 0.736 s (the "
             "Connector row above says what was measured)",),
)


def conformance_section() -> list[str]:
    """The page's lines about Webots' physics regression tests."""
    c = CONFORMANCE
    return [
        "## Webots' physics regression tests",
        "",
        "Webots ships regression tests of its physics (`tests/physics` in its repository: worlds whose checks",
        "assert what real Webots does). Half of them are kept beside this project as its conformance target,",
        "re-expressed as Python checks with Webots' expected values, and `make test` runs each of them through",
        "the `dualtwin` command. The Webots twin passes "
        f"**{c.tests[0]}/{c.tests[1]} tests, {c.checks[0]}/{c.checks[1]} checks**.",
        "The other half is kept back by the maintainers; it checks the same mechanisms with other worlds and",
        "numbers. Still failing:",
        "",
        *[f"- {what}" for what in c.failing],
        "",
    ]


def render_markdown() -> str:
    """The coverage page (deterministic: registry order within categories)."""
    counts = {s: sum(1 for c in REGISTRY if c.status == s) for s in STATUSES}
    lines = [
        "<!-- generated by python -m dualtwin.webots.coverage from dualtwin/webots/coverage.py; do not edit -->",
        "",
        "# Webots coverage",
        "",
        "What the headless Webots twin does with every Webots R2023b node and device. Generated from the",
        "registry in `dualtwin/webots/coverage.py`, which the tests hold to the code.",
        "",
        "- **supported**: Webots' semantics, tested;",
        "- **partial**: works, within the limits given;",
        "- **visual**: kept in the scene tree (supervisors can read it), nothing to simulate headless; Camera",
        "  images draw at most its flat colour;",
        "- **not**: parsed and kept, without effect yet.",
        "",
        "Numbers no Webots field takes are not passed to ODE, which aborts the whole process on them (the "
        "`libode8` package is built with its assertions; Webots' own ODE is not): a `nan` or `inf` in any field "
        "of a world or PROTO keeps the field's default, and a joint axis of length zero takes the joint's "
        "default axis, each with a warning naming the place. Finite but extreme magnitudes (a sphere of "
        "radius 1e300, an anchor at 1e30 m) can still make ODE abort inside its step.",
        "",
        "Totals: " + ", ".join(f"{counts[s]} {s}" for s in STATUSES) + f" ({len(REGISTRY)} entries).",
        "",
    ]
    for key, title in CATEGORIES.items():
        lines += [f"## {title}", "", "| node | status | notes |", "|---|---|---|"]
        for c in REGISTRY:
            if c.category == key:
                name = f"`{c.name}`" + ("" if c.node else " (controller only)")
                lines.append(f"| {name} | {c.status} | {c.reason.replace('|', '/')} |")
        lines.append("")
    lines += conformance_section()
    lines += api_section()
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """Write the page to ``docs/webots-coverage.md`` of the checkout (or the path given)."""
    import argparse

    parser = argparse.ArgumentParser(prog="python -m dualtwin.webots.coverage", description=main.__doc__)
    parser.add_argument("target", nargs="?", type=Path,
                        default=Path(__file__).resolve().parents[3] / "docs" / "webots-coverage.md",
                        help="where to write the page (default: docs/webots-coverage.md of this checkout)")
    target = parser.parse_args(sys.argv[1:] if argv is None else argv).target
    target.write_text(render_markdown(), encoding="utf-8")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
