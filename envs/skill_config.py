"""How the robot's skills move and grasp: their geometry, timing and the v3 pick's corrections.

:class:`SkillConfig` holds every number of :mod:`ipbench.envs.skills` (heights, openings,
waiting times, the guarded descent's force) with its source; its defaults are the released
skills (every released id), and :data:`V3_SKILLS` switches on ``Sorting-v3``'s picks: straight
descents and lifts, and the retries and regrasps planned from the wrist wrench and the pads'
contact sensing.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SkillConfig", "V3_SKILLS"]


@dataclass(frozen=True)
class SkillConfig:
    """Geometry and timing of the skills (m, s).

    Attributes
    ----------
    transit_height : TCP height above the table for moves with an empty gripper (clears the
        tallest object, 0.29 m, with the pads below the TCP).
    carry_clearance : while carrying, the held object's bottom stays this high above the
        table (so it passes over the other objects) where the arm can reach that high.
    min_grasp_height : lowest TCP height above the table (the pads are 6 cm tall).
    grasp_depth : how far below the reported position the TCP goes (grasping a segment's
        centroid a little lower holds tall objects better), clamped by ``min_grasp_height``.
    open_width, close_time, release_time : gripper half-opening (m) and waiting times (the
        close time counts from when the closing fingers' target reaches zero).
    finger_speed : how fast each finger's target moves when closing (m/s; 0.1 closes the
        jaws at 0.2 m/s, an electric parallel gripper's speed): fingers that slam shut on an
        object would launch light neighbours. ``None`` steps the target shut at once
        (``Sorting-v0``).
    min_held_width : a grasp holds something only if the jaws stay at least this far apart.
    bin_release_clearance : height of the held object's bottom above the bin rim at release.
    min_opening : narrowest jaw opening a pick pre-shapes to (m, full opening).
    guard_force : a pick's descent stops where the contact force on the gripper exceeds this
        (N), as a robot with a wrist force sensor would; ``None`` descends blind.
    line_step : a pick's descent and the lift after its grasp are vertical lines of the TCP
        (a robot controller's linear move, as Motoman's MOVL), executed through IK waypoints
        this far apart (m) (:meth:`~ipbench.envs.robot.RobotController.move_path`). A
        joint-space move from the transit height bows the TCP up to 4 cm off the vertical in
        its last 10 cm (measured on ``SortingCluttered-v3``'s picks), sweeping the fingers
        into the neighbours; the bow shrinks with the square of the segment, so 0.02 keeps it
        under 0.2 mm, below the IK's 1 mm tolerance. It also sets three things of a
        set-down (into a bin or the inspection area): where the arm cannot reach the planned
        carry height over the place, the carry goes as high as it reaches there (heights tried
        this far apart, down to the release height), instead of failing with the object in
        hand; the object is lowered to its release height on a vertical line that stops where
        the wrist wrench senses it supported (the hanging load halved: it rests on something,
        as on a bottle standing out of a full bin, which one joint-space move rams at over
        100 N and can fling out); and after letting go the open jaws rise straight up to the
        carry height instead of one joint-space move to the transit height, which can swing
        them through what they just set down. ``None``: one joint-space move each (released
        ids).
    line_speed : the TCP's peak speed on those lines (m/s): 0.25, the reduced speed of
        ISO 10218-1:2011 (5.6), a speed at which the arm's position servos track the line
        within about 2 mm (at the released descent's quarter joint speed the TCP runs at up
        to 0.6 m/s and lags up to 13 mm off the line; measured on a lying bottle's pick).
    approach_rise : a pick's transit move ends this much above the transit height (m), and
        its straight descent starts there: a joint-space move between two transit poses sags
        below both, by up to 0.08 m over the table (the lowest TCP on
        ``SortingCluttered-v3``'s approaches: 0.28 m for a 0.36 m transit height), where the
        open jaws meet the tallest objects (0.29 m). The jaws then pre-shape to the pick's
        opening over the target rather than before the arm leaves where it was (over a bin,
        where closing jaws catch what sticks out of it). ``None``: the transit height, jaws
        pre-shaped first (released ids).
    early_contact : a guarded descent that stops more than this above the planned TCP height
        (m) landed on something: the finger under the wrist wrench's centre of pressure (a
        load centred within ``finger_inset`` of a pad's face; elsewhere it is the palm) is
        moved in by ``finger_inset`` and the descent tried again, at most
        ``contact_retries`` times. 0.03 is the pads' half height (``gripper.xml``): stopped
        higher, the pads' lower edges hang above the planned TCP height. ``None``: the jaws
        close wherever the descent stopped (released ids).
    finger_inset : how far a finger that landed on something moves in (m): 0.018, the
        finger's thickness from the pad's face to the finger's outer face (``gripper.xml``:
        8 mm pad, finger box 2-18 mm behind the pad's face), so that a finger that landed on
        the edge of a neighbour comes down beside it. The other finger stays where it was.
    contact_retries : how many descents may be tried again: 2, one per finger.
    rim_regrasp : when the jaws close on something (wider than ``min_held_width``) that a
        pad does not touch, it is wider above that pad (a flared rim meets the finger box
        above the pad): the jaws open and close again this much higher (m). 0.025 is the
        pad's height below the finger box (pads 30 mm below the TCP, finger box 5 mm below:
        ``gripper.xml``). ``None``: no second close (released ids).
    balance_lift : the first lift after closing goes this high (m) at the descent's speed
        and the wrist wrench is read there; a load whose centre of mass hangs more than
        ``com_tolerance`` off the TCP along the jaws' width is set down and grasped again
        through it (:func:`~ipbench.envs.grasp_sensing.load_offset`). 0.02 clears the
        table for the longest object (a 290 mm bottle, ``assets/objects/families.py``)
        tilted by up to 8 degrees in the jaws: 0.145 m x sin 8 deg = 0.02 m. ``None``: one
        lift straight to the transit height (released ids).
    balance_time : how long the arm holds still before the wrench is read (s): 0.1, a 10 Hz
        low-pass of the sensor against the lift's vibration.
    com_tolerance : largest centre-of-mass offset along the jaws' width that is kept (m):
        0.005, a quarter of the 15-22 mm by which a filled bottle's or carton's centre of
        mass sits below its bounding box's centre, the offset the regrasp removes
        (``assets/objects/family_samplers.py``: filled to the shoulder).
    min_load : the smallest vertical load the wrench is read from (N): 1.0, half the weight
        of the lightest object (a 0.2 kg juice box, ``assets/objects/families.py``).
    """

    transit_height: float = 0.36
    carry_clearance: float = 0.31
    min_grasp_height: float = 0.04
    grasp_depth: float = 0.02
    open_width: float = 0.105
    close_time: float = 0.3
    finger_speed: float | None = 0.1
    release_time: float = 0.35
    min_held_width: float = 0.004
    bin_release_clearance: float = 0.10
    min_opening: float = 0.03
    guard_force: float | None = 20.0
    line_step: float | None = None
    line_speed: float = 0.25
    approach_rise: float | None = None
    early_contact: float | None = None
    finger_inset: float = 0.018
    contact_retries: int = 2
    rim_regrasp: float | None = None
    balance_lift: float | None = None
    balance_time: float = 0.1
    com_tolerance: float = 0.005
    min_load: float = 1.0


V3_SKILLS = SkillConfig(
    line_step=0.02, approach_rise=0.08, early_contact=0.03, rim_regrasp=0.025, balance_lift=0.02
)
"""``Sorting-v3``'s skills: the released ones plus the sensed retries and regrasps of a pick."""
