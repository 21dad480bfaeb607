"""A recording stand-in of the part of SofaPython3's ``Sofa.Core`` API a scene file uses.

SOFA is not installable from the package registries, so the exported scene is built here on
this stand-in: every node, object and data assignment is recorded, and an object whose type
or parameter is not in :data:`COMPONENTS` (the names read from SOFA's and the plugins' sources
and tutorials, as the scene cites them) raises, so a misspelt component or parameter fails a
test instead of failing in SOFA.
"""

from __future__ import annotations

import sys
import types

_COMMON = {"name", "template", "printLog"}
#: component -> the parameters a scene may give it (beside name, template, printLog)
COMPONENTS = {
    "RequiredPlugin": {"pluginName"},
    "VisualStyle": {"displayFlags"},
    "FreeMotionAnimationLoop": set(),
    "QPInverseProblemSolver": {"epsilon", "maxIterations", "tolerance"},
    "GenericConstraintSolver": {"maxIterations", "tolerance"},
    "EulerImplicitSolver": {"firstOrder", "rayleighStiffness", "rayleighMass"},
    "SparseLDLSolver": set(),
    "CGLinearSolver": {"iterations", "threshold", "tolerance"},
    "GenericConstraintCorrection": {"linearSolver"},
    "UncoupledConstraintCorrection": {"compliance"},
    "MechanicalObject": {"position", "rest_position", "showObject", "showObjectScale"},
    "FixedProjectiveConstraint": {"indices"},
    "UniformMass": {"totalMass"},
    "RestShapeSpringsForceField": {"points", "stiffness"},
    "ArticulatedHierarchyContainer": set(),
    "ArticulatedSystemMapping": {"input1", "input2", "output"},
    "ArticulationCenter": {"parentIndex", "childIndex", "posOnParent", "posOnChild"},
    "Articulation": {"translation", "rotation", "rotationAxis", "articulationIndex"},
    "JointActuator": {"index", "applyForce", "minAngle", "maxAngle", "maxAngleVariation"},
    "PositionEffector": {"indices", "useDirections", "effectorGoal"},
    "MeshVTKLoader": {"filename"},
    "MeshOBJLoader": {"filename"},
    "MeshTopology": {"src"},
    "OglModel": {"src", "color"},
    "TetrahedronAnisotropicForceField": {"youngModulus", "poissonRatio", "elasticitySymmetry", "anisotropyParameters",
                                         "anisotropyDirections", "drawHeterogeneousTetra"},
    "TetrahedronFEMForceField": {"youngModulus", "poissonRatio", "method"},
    "SubsetMultiMapping": {"input", "output", "indexPairs"},
    "RigidMapping": {"globalToLocalCoords", "rigidIndexPerPoint", "index"},
}


class Object:
    """A recorded component: its type, parameters and the node holding it."""

    def __init__(self, node, type_, params):
        self.node, self.type, self.params = node, type_, dict(params)
        self.name = params.get("name", type_)

    def __getattr__(self, key):
        params = self.__dict__.get("params", {})
        if key in params:
            return params[key]
        raise AttributeError(f"{self.__dict__.get('type')} has no data {key!r}")

    def getLinkPath(self) -> str:
        return f"{self.node.getLinkPath()}/{self.name}"


class Node:
    """A recorded node: children and objects in order, data set on it, every parent."""

    def __init__(self, name: str = "root"):
        self.name, self.children, self.objects, self.parents, self.data = name, [], [], [], {}

    def addChild(self, child):
        node = child if isinstance(child, Node) else Node(str(child))
        if any(c.name == node.name for c in self.children):
            raise ValueError(f"{self.getLinkPath()}: a child named {node.name!r} exists")
        node.parents.append(self)
        self.children.append(node)
        return node

    def addObject(self, type_, **params):
        if isinstance(type_, Controller):  # a Python controller instance
            self.objects.append(type_)
            return type_
        if type_ not in COMPONENTS:
            raise ValueError(f"unknown SOFA component {type_!r}")
        unknown = set(params) - COMPONENTS[type_] - _COMMON
        if unknown:
            raise ValueError(f"{type_}: unknown parameters {sorted(unknown)}")
        obj = Object(self, type_, params)
        if any(getattr(o, "name", None) == obj.name for o in self.objects):
            raise ValueError(f"{self.getLinkPath()}: an object named {obj.name!r} exists")
        self.objects.append(obj)
        return obj

    def __getattr__(self, key):
        for item in self.__dict__.get("children", []) + self.__dict__.get("objects", []):
            if getattr(item, "name", None) == key:
                return item
        if key in self.__dict__.get("data", {}):
            return self.__dict__["data"][key]
        raise AttributeError(f"node {self.__dict__.get('name')!r} has no child, object or data {key!r}")

    def __setattr__(self, key, value):
        if key in ("name", "children", "objects", "parents", "data"):
            object.__setattr__(self, key, value)
        else:
            self.data[key] = value

    def getLinkPath(self) -> str:
        if not self.parents:
            return "@"
        up = self.parents[0].getLinkPath()
        return f"{up}/{self.name}" if up != "@" else f"@/{self.name}"

    # -- reading the record ----------------------------------------------------------------
    def walk(self):
        """Every (node, object) under this node, each node once, depth first."""
        seen = set()

        def visit(node):
            if id(node) in seen:
                return
            seen.add(id(node))
            for o in node.objects:
                yield node, o
            for c in node.children:
                yield from visit(c)

        yield from visit(self)

    def find(self, type_):
        """The recorded objects of a component type, in graph order."""
        return [o for _, o in self.walk() if getattr(o, "type", None) == type_]


class Controller:
    """Stand-in of ``Sofa.Core.Controller``."""

    def __init__(self, *args, **kwargs):
        self.name = kwargs.get("name", type(self).__name__)


def install(monkeypatch) -> None:
    """Put the stand-in in ``sys.modules`` as ``Sofa`` and ``Sofa.Core`` for one test."""
    core = types.ModuleType("Sofa.Core")
    core.Node, core.Controller = Node, Controller
    sofa = types.ModuleType("Sofa")
    sofa.Core = core
    monkeypatch.setitem(sys.modules, "Sofa", sofa)
    monkeypatch.setitem(sys.modules, "Sofa.Core", core)
