"""Small OpenSim 4 model files written by the tests: a chain ground -> a -> b with offset frames,
a CustomJoint of general axes and functions, contact meshes and ligaments; each part replaceable."""

from __future__ import annotations

from pathlib import Path

#: The CustomJoint between a and b: a few axes not along x, y, z, a slope and intercept, a constant.
CUSTOM_AXES = """
<SpatialTransform>
  <TransformAxis name="rotation1"><coordinates>q1</coordinates><axis>0 0 2</axis>
    <LinearFunction name="function"><coefficients>-1 0.1</coefficients></LinearFunction></TransformAxis>
  <TransformAxis name="rotation2"><coordinates>q2</coordinates><axis>1 1 0</axis>
    <LinearFunction name="function"><coefficients>0.5 0</coefficients></LinearFunction></TransformAxis>
  <TransformAxis name="rotation3"><coordinates>q3</coordinates><axis>0 1 0</axis></TransformAxis>
  <TransformAxis name="translation1"><coordinates>q4</coordinates><axis>1 0 0</axis>
    <LinearFunction name="function"><coefficients>1 0</coefficients></LinearFunction></TransformAxis>
  <TransformAxis name="translation2"><axis>0 1 0</axis><Constant name="function"><value>0.02</value></Constant></TransformAxis>
  <TransformAxis name="translation3"><coordinates>q5</coordinates><axis>0 0.6 0.8</axis>
    <MultiplierFunction name="function"><function><LinearFunction name="function"><coefficients>1 0</coefficients>
    </LinearFunction></function><scale>2</scale></MultiplierFunction></TransformAxis>
</SpatialTransform>"""

COORDS = "".join(
    f'<Coordinate name="q{i}"><default_value>{v}</default_value><range>-3 3</range></Coordinate>'
    for i, v in enumerate((0.3, -0.2, 0.4, 0.01, -0.015), start=1)
)

LIGAMENT = """
<Blankevoort1991Ligament name="{name}">
  <GeometryPath name="geometrypath"><PathPointSet><objects>
    <PathPoint name="p1"><socket_parent_frame>{frame1}</socket_parent_frame><location>{p1}</location></PathPoint>
    {via}
    <PathPoint name="p2"><socket_parent_frame>{frame2}</socket_parent_frame><location>{p2}</location></PathPoint>
  </objects></PathPointSet>{wraps}</GeometryPath>
  <linear_stiffness>{k}</linear_stiffness>{slack}
</Blankevoort1991Ligament>"""


def ligament(
    name="lig",
    frame1="/bodyset/a",
    p1="0.01 0.02 0.03",
    frame2="/bodyset/b",
    p2="0.02 -0.03 0.01",
    k=1000,
    slack="<slack_length>0.05</slack_length>",
    via="",
    wraps="",
) -> str:
    return LIGAMENT.format(
        name=name, frame1=frame1, p1=p1, frame2=frame2, p2=p2, k=k, slack=slack, via=via, wraps=wraps
    )


CONTACT = """
<Smith2018ArticularContactForce name="contact">
  <socket_target_mesh>/contactgeometryset/mesh_b</socket_target_mesh>
  <socket_casting_mesh>/contactgeometryset/mesh_a</socket_casting_mesh>
  <min_proximity>0</min_proximity><max_proximity>0.02</max_proximity>
  <elastic_foundation_formulation>{formulation}</elastic_foundation_formulation>
  <use_lumped_contact_model>{lumped}</use_lumped_contact_model>
</Smith2018ArticularContactForce>"""

MESHES = """
<Smith2018ContactMesh name="mesh_a"><socket_frame>/bodyset/a/a_offset</socket_frame>
  <mesh_file>{file_a}</mesh_file><elastic_modulus>{E_a}</elastic_modulus><poissons_ratio>{nu_a}</poissons_ratio>
  <thickness>{h_a}</thickness></Smith2018ContactMesh>
<Smith2018ContactMesh name="mesh_b"><socket_frame>/bodyset/b</socket_frame>
  <mesh_file>{file_b}</mesh_file><elastic_modulus>{E_b}</elastic_modulus><poissons_ratio>{nu_b}</poissons_ratio>
  <thickness>{h_b}</thickness></Smith2018ContactMesh>"""


def model_text(*, joint_ab=None, forces="", constraints="", meshes="", wraps="", version="40000", doctype="") -> str:
    """The model: ground -> (CustomJoint j0, offsets both sides) -> a -> (joint_ab) -> b."""
    if joint_ab is None:
        joint_ab = f"""<CustomJoint name="j1"><socket_parent_frame>a_off</socket_parent_frame>
          <socket_child_frame>b_off</socket_child_frame><coordinates>{COORDS}</coordinates>
          <frames>
            <PhysicalOffsetFrame name="a_off"><socket_parent>/bodyset/a</socket_parent>
              <translation>0.01 -0.4 0.002</translation><orientation>0.1 -0.2 0.3</orientation></PhysicalOffsetFrame>
            <PhysicalOffsetFrame name="b_off"><socket_parent>/bodyset/b</socket_parent>
              <translation>-0.003 0.02 0.001</translation><orientation>-0.05 0.02 0.4</orientation></PhysicalOffsetFrame>
          </frames>{CUSTOM_AXES}</CustomJoint>"""
    return f"""<?xml version="1.0" encoding="UTF-8" ?>{doctype}
<OpenSimDocument Version="{version}">
<Model name="toy">
  <Ground name="ground"/>
  <length_units>m</length_units>
  <BodySet name="bodyset"><objects>
    <Body name="a"><mass>1</mass><inertia>0.01 0.01 0.01 0 0 0</inertia><components><PhysicalOffsetFrame name="a_offset"><socket_parent>..</socket_parent>
      <translation>0.005 -0.41 0.003</translation><orientation>3.0 0.01 -3.05</orientation></PhysicalOffsetFrame>
      </components>
      <WrapObjectSet name="wrapobjectset"><objects>{wraps}</objects></WrapObjectSet></Body>
    <Body name="b"><mass>1</mass><inertia>0.01 0.01 0.01 0 0 0</inertia></Body>
  </objects></BodySet>
  <JointSet name="jointset"><objects>
    <CustomJoint name="j0"><socket_parent_frame>/ground</socket_parent_frame><socket_child_frame>/bodyset/a</socket_child_frame>
      <coordinates><Coordinate name="g1"><default_value>0.7</default_value></Coordinate>
        <Coordinate name="g2"><default_value>0.9</default_value></Coordinate></coordinates>
      <SpatialTransform>
        <TransformAxis name="rotation1"><coordinates>g1</coordinates><axis>1 0 0</axis></TransformAxis>
        <TransformAxis name="translation2"><coordinates>g2</coordinates><axis>0 1 0</axis></TransformAxis>
      </SpatialTransform></CustomJoint>
    {joint_ab}
  </objects></JointSet>
  <ConstraintSet name="constraintset"><objects>{constraints}</objects></ConstraintSet>
  <ForceSet name="forceset"><objects>{forces}</objects></ForceSet>
  <ContactGeometrySet name="contactgeometryset"><objects>{meshes}</objects></ContactGeometrySet>
</Model>
</OpenSimDocument>
"""


def write_model(folder: Path, name: str = "toy.osim", **parts) -> Path:
    path = Path(folder) / name
    path.write_text(model_text(**parts), encoding="utf-8")
    return path
