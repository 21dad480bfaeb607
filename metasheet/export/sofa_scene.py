"""SOFA scene of a metasheet robot: ``runSofa scene.py`` in a folder ``metasheet export sofa`` wrote.

This file is copied into the export as ``scene.py`` and runs inside SOFA's Python 3
(SofaPython3), not inside metasheet: it imports neither metasheet nor numpy, and reads
``robot.json``, ``sheets.vtk`` and ``elements.txt`` beside it. Targets SOFA v24.06 with the
plugins SoftRobots, SoftRobots.Inverse, ArticulatedSystemPlugin and, for the anisotropic
sheets, the authors' Anisotropy plugin (github.com/VannesteFelix/anisotropy). Units: mm, kg,
s, so stresses in kPa (``robot.json`` ``units``).

The graph follows the SoftRobots Tripod tutorial (SofaDefrost/SoftRobots,
examples/tutorials/Tripod: ``s90servo.py`` for a servo, ``tripod.py`` for the rigidified grips
joined to the servo wheels and a free centre, ``step8.py`` for the inverse components) and the
authors' sheets (VannesteFelix/anisotropy, examples/Tripod/details/elasticbody.py):

* both sheets are one elastic body (``Sheets``): ``MeshVTKLoader`` + ``MeshTopology``, a
  ``UniformMass``, and ``TetrahedronAnisotropicForceField`` with per-element ``youngModulus``
  (E_t), ``poissonRatio`` (nu_t), ``anisotropyParameters`` [2, E_l, nu_tl, mu_l] (2 =
  transverse isotropic, the plugin's enum) and ``anisotropyDirections`` (the soft axis l);
  with ``ANISOTROPIC = False`` (a SOFA without the plugin) a ``TetrahedronFEMForceField``,
  isotropic with E_t and nu_t: the sheets then lose their anisotropy, and with it the rod's roll
  about its own axis (the paper's sixth DOF);
* the grips are rigid, as in metasheet: each arm's tip box moves with its servo's wheel, both
  centres with the rod (the tutorial's rigidification: ``RigidParts`` mapped from the six wheels
  and the rod by ``SubsetMultiMapping``, the gripped nodes by ``RigidMapping``, the sheets'
  nodes gathered by a second ``SubsetMultiMapping``);
* each servo is the tutorial's servo: a fixed body frame at the pivot (x along the servo axis,
  y along the horn at 0 deg, z along the horn at 90 deg), a ``Vec1`` angle equal to
  metasheet's motor angle [rad] (0 = horizontal horn reaching inwards, 90 deg = vertical) and a
  wheel frame from ``ArticulatedSystemMapping``;
* ``INVERSE = True``: ``QPInverseProblemSolver``, a ``JointActuator`` per servo within the
  stroke (``minAngle``, ``maxAngle`` as the angle itself, absolute) and a ``PositionEffector``
  on the rod's frame towards the ``Goal`` node; ``False``: each servo angle is held by a stiff
  spring at the angles of ``PROGRAM`` (a ``metasheet robot path`` program.csv) played in time,
  or at rest.

Not run in SOFA where it was written (SOFA installs from conda or binaries, not PyPI): metasheet
tests the graph on a stand-in of the ``Sofa.Core`` API and reads the files back into its own robot.
"""

import json
import os

HERE = os.path.dirname(os.path.abspath(__file__))
#: the authors' force field (Anisotropy plugin); False: SOFA's isotropic TetrahedronFEMForceField
ANISOTROPIC = True
#: True: the inverse model (QP); False: the servos follow PROGRAM, or hold their rest angles
INVERSE = True
#: a metasheet motor program (program.csv of `metasheet robot path`) played when INVERSE is False
PROGRAM = None

PLUGINS = ["ArticulatedSystemPlugin", "Sofa.Component.AnimationLoop", "Sofa.Component.Constraint.Lagrangian.Correction",
           "Sofa.Component.Constraint.Lagrangian.Solver", "Sofa.Component.Constraint.Projective",
           "Sofa.Component.IO.Mesh", "Sofa.Component.LinearSolver.Direct", "Sofa.Component.LinearSolver.Iterative",
           "Sofa.Component.Mapping.Linear", "Sofa.Component.Mapping.NonLinear", "Sofa.Component.Mass",
           "Sofa.Component.ODESolver.Backward", "Sofa.Component.SolidMechanics.FEM.Elastic",
           "Sofa.Component.SolidMechanics.Spring", "Sofa.Component.StateContainer",
           "Sofa.Component.Topology.Container.Constant", "Sofa.Component.Visual", "SoftRobots"]


def read_vtk_points(path):
    """The POINTS of a legacy ASCII VTK file [mm], as lists (the rigid split needs them at
    scene creation, before the loader's init)."""
    with open(path) as f:
        words = f.read().split()
    at = words.index("POINTS")
    n = int(words[at + 1])
    vals = [float(w) for w in words[at + 3:at + 3 + 3 * n]]
    return [vals[3 * i:3 * i + 3] for i in range(n)]


def read_elements(path):
    """Rows of ``elements.txt``: sheet, dx, dy, dz, E_t, E_l, nu_t, nu_tl, mu_l (kPa)."""
    with open(path) as f:
        return [[float(w) for w in line.split()] for line in f if line.strip() and not line.startswith("#")]


def read_program(path):
    """(times [s], six angles [rad] per sample) of a metasheet program.csv."""
    import csv
    import math

    with open(path) as f:
        rows = list(csv.DictReader(f))
    return ([float(r["time_s"]) for r in rows],
            [[math.radians(float(r[f"motor{k}_deg"])) for k in range(6)] for r in rows])


def add_sheets(parent, robot, elements, anisotropic):
    """The elastic body of both sheets, under ``parent`` (its dofs are mapped: :func:`rigidify`)."""
    body = parent.addChild("Sheets")
    body.addObject("MeshVTKLoader", name="loader", filename=os.path.join(HERE, robot["mesh"]))
    body.addObject("MeshTopology", name="container", src="@loader")
    body.addObject("MechanicalObject", name="dofs", template="Vec3", position="@loader.position")
    body.addObject("UniformMass", name="mass", totalMass=robot["sheets_mass_kg"])
    E_t = [e[4] for e in elements]
    nu_t = [e[6] for e in elements]
    if anisotropic:
        body.addObject("TetrahedronAnisotropicForceField", name="elasticity", youngModulus=E_t, poissonRatio=nu_t,
                       elasticitySymmetry="transverseIsotropic",
                       anisotropyParameters=[[2, e[5], e[7], e[8]] for e in elements],
                       anisotropyDirections=[e[1:4] for e in elements], drawHeterogeneousTetra=False)
    else:
        # isotropic fallback: E_t and nu_t only; the fibres, E_l, nu_tl and mu_l are lost
        body.addObject("TetrahedronFEMForceField", name="elasticity", youngModulus=E_t, poissonRatio=nu_t,
                       method="large")
    return body


def add_servo(parent, k, servo, inverse):
    """Servo ``k``: fixed body, angle (metasheet's motor angle [rad]), wheel (tutorial's s90servo)."""
    node = parent.addChild(f"Servo{k}")
    frame = servo["frame"]
    body = node.addChild("ServoBody")
    body.addObject("MechanicalObject", name="dofs", template="Rigid3", position=[frame])
    body.addObject("FixedProjectiveConstraint", indices=0)
    body.addObject("UniformMass", totalMass=servo["horn_mass_kg"])
    angle = node.addChild("Articulation")
    a0 = servo["rest_angle_rad"]
    angle.addObject("MechanicalObject", name="dofs", template="Vec1", position=[[a0]], rest_position=[[a0]])
    if not inverse:  # the commanded angle: a stiff spring to the rest position a controller sets
        angle.addObject("RestShapeSpringsForceField", name="command", points=0, stiffness=1e9)
    angle.addObject("UniformMass", totalMass=servo["horn_mass_kg"])
    angle.addObject("ArticulatedHierarchyContainer")
    wheel = angle.addChild("ServoWheel")
    wheel.addObject("MechanicalObject", name="dofs", template="Rigid3", position=[frame, frame])
    wheel.addObject("ArticulatedSystemMapping", input1="@../dofs", input2="@../../ServoBody/dofs", output="@./")
    centre = angle.addChild("ArticulationCenter")
    centre.addObject("ArticulationCenter", parentIndex=0, childIndex=1, posOnParent=[0.0, 0.0, 0.0],
                     posOnChild=[0.0, 0.0, 0.0])
    joint = centre.addChild("Articulations")
    joint.addObject("Articulation", translation=False, rotation=True, rotationAxis=[1, 0, 0], articulationIndex=0)
    if inverse:
        act = angle.addChild("Actuator")
        act.addObject("JointActuator", name="actuator", template="Vec1", index=0, applyForce=True,
                      minAngle=servo["angle_min_rad"], maxAngle=servo["angle_max_rad"],
                      maxAngleVariation=servo["max_step_rad"])
    return node


def rigidify(parent, servos, rod, robot, elements, points, anisotropic):
    """The rigid grips: ``RigidParts`` (six arm grips on the servos' wheels, both centres on
    the rod), the free nodes, and the sheets (:func:`add_sheets`) whose dofs are gathered from
    both (the tutorial's Rigidify, written out)."""
    groups = [s["grip_nodes"] for s in robot["servos"]] + [robot["rod"]["grip_nodes"]]
    frames = [s["grip_frame"] for s in robot["servos"]] + [robot["rod"]["frame"]]
    gripped, owner = [], []
    for g, nodes in enumerate(groups):
        gripped += nodes
        owner += [g] * len(nodes)
    rank = {v: i for i, v in enumerate(gripped)}
    free = [i for i in range(len(points)) if i not in rank]
    free_rank = {v: i for i, v in enumerate(free)}
    pairs = []
    for i in range(len(points)):
        pairs += [1, rank[i]] if i in rank else [0, free_rank[i]]
    node = parent.addChild("RigidifiedStructure")
    deformable = node.addChild("DeformableParts")
    deformable.addObject("MechanicalObject", name="dofs", template="Vec3", position=[points[i] for i in free])
    rigid = node.addChild("RigidParts")
    rigid.addObject("MechanicalObject", name="dofs", template="Rigid3", position=frames)
    wheels = [s.Articulation.ServoWheel for s in servos]
    # frame 1 of each wheel (frame 0 is the servo body's copy), frame 0 of the rod
    rigid.addObject("SubsetMultiMapping", name="mapping", input=[w.getLinkPath() for w in wheels] + [rod.getLinkPath()],
                    output="@./", indexPairs=[v for k in range(len(wheels)) for v in (k, 1)] + [len(wheels), 0])
    for w in wheels:  # RigidParts is a child of every node it is mapped from
        w.addChild(rigid)
    rod.addChild(rigid)
    particles = rigid.addChild("RigidifiedParticles")
    particles.addObject("MechanicalObject", name="dofs", template="Vec3", position=[points[i] for i in gripped])
    particles.addObject("RigidMapping", name="mapping", globalToLocalCoords=True, rigidIndexPerPoint=owner)
    sheets = add_sheets(deformable, robot, elements, anisotropic)
    particles.addChild(sheets)
    sheets.addObject("SubsetMultiMapping", name="mapping", template="Vec3,Vec3",
                     input=[deformable.dofs.getLinkPath(), particles.dofs.getLinkPath()],
                     output="@./dofs", indexPairs=pairs)
    return node


def add_rod(parent, robot):
    """The rod and the maze fixed to it: one rigid body whose frame is the effector."""
    rod = parent.addChild("Rod")
    r = robot["rod"]
    rod.addObject("MechanicalObject", name="dofs", template="Rigid3", position=[r["frame"]])
    rod.addObject("UniformMass", totalMass=r["mass_kg"])
    maze = rod.addChild("Maze")
    maze.addObject("MeshOBJLoader", name="loader", filename=os.path.join(HERE, r["maze_mesh"]))
    maze.addObject("OglModel", name="visual", src="@loader", color=[0.8, 0.8, 0.8, 1.0])
    maze.addObject("RigidMapping", name="mapping", index=0)
    return rod


def add_inverse(root, rod, robot):
    """The goal (a rigid frame the user moves) and the rod's effector towards it."""
    goal = root.addChild("Goal")
    goal.addObject("EulerImplicitSolver", firstOrder=True)
    goal.addObject("CGLinearSolver", iterations=100, threshold=1e-5, tolerance=1e-5)
    goal.addObject("MechanicalObject", name="dofs", template="Rigid3", position=[robot["rod"]["frame"]])
    goal.addObject("UncoupledConstraintCorrection", compliance=[1e-10] * 7)
    effector = rod.addChild("Effector")
    effector.addObject("PositionEffector", name="effector", template="Rigid3", indices=0,
                       useDirections=[1, 1, 1, 1, 1, 1], effectorGoal=goal.dofs.getLinkPath() + ".position")
    return goal


def program_controller(root, servos, program_file):
    """A controller that sets each servo's commanded angle from a motor program, by time."""
    import bisect

    import Sofa.Core

    times, angles = read_program(program_file)

    class Program(Sofa.Core.Controller):
        def onAnimateBeginEvent(self, event):
            t = root.time.value
            row = angles[max(0, bisect.bisect_right(times, t) - 1)]
            for k, servo in enumerate(servos):
                servo.Articulation.dofs.rest_position = [[row[k]]]

    return root.addObject(Program(name="program"))


def createScene(rootNode):
    """The robot of ``robot.json`` (see the module docstring)."""
    with open(os.path.join(HERE, "robot.json")) as f:
        robot = json.load(f)
    elements = read_elements(os.path.join(HERE, robot["elements"]))
    points = read_vtk_points(os.path.join(HERE, robot["mesh"]))
    plugins = PLUGINS + (["SoftRobots.Inverse"] if INVERSE else []) + (["Anisotropy"] if ANISOTROPIC else [])
    rootNode.addObject("RequiredPlugin", pluginName=plugins)
    rootNode.gravity = robot["gravity_mm_s2"]
    rootNode.dt = robot["dt_s"]
    rootNode.addObject("VisualStyle", displayFlags="showBehaviorModels showVisualModels")
    rootNode.addObject("FreeMotionAnimationLoop")
    if INVERSE:
        rootNode.addObject("QPInverseProblemSolver", name="solver", epsilon=robot["qp_epsilon"])
    else:
        rootNode.addObject("GenericConstraintSolver", name="solver", maxIterations=1000, tolerance=1e-5)
    sim = rootNode.addChild("Simulation")
    # the authors' inverse scene: implicit Euler with Rayleigh stiffness 0.01 (SOFA's default is 0)
    sim.addObject("EulerImplicitSolver", firstOrder=False, rayleighStiffness=robot["rayleigh_stiffness"],
                  rayleighMass=robot["rayleigh_mass"])
    # scalar blocks: the system mixes Vec1 (servo angles), Vec3 (sheets) and Rigid3 (rod) dofs
    sim.addObject("SparseLDLSolver", name="linearSolver", template="CompressedRowSparseMatrixd")
    sim.addObject("GenericConstraintCorrection", linearSolver="@linearSolver")
    servos = [add_servo(sim, k, s, INVERSE) for k, s in enumerate(robot["servos"])]
    rod = add_rod(sim, robot)
    rigidify(sim, servos, rod, robot, elements, points, ANISOTROPIC)
    if INVERSE:
        add_inverse(rootNode, rod, robot)
    elif PROGRAM is not None:
        program_controller(rootNode, servos, PROGRAM)
    return rootNode
