"""
What the contact query's points become: only those that touch, the ignored bodies left out.

PyBullet's ``getContactPoints`` returns the points of its contact manifolds,
which Bullet keeps while shapes are within its contact margin: bodies still
apart (up to about a centimetre, with no normal force) have points too. A
review found learning episodes ended, and farm runs judged, on such near
misses (7 mm away, "touched"). The rule is checked here on the points
themselves, as PyBullet gives them: (flag, body a, body b, link a, link b,
position on a, position on b, normal on b, distance, normal force, ...).
"""

from r2d2_sim.physics.records import contact_records


def point(body_b, distance_m, force_n, link_a=0):
    """Return a contact point as getContactPoints gives it."""
    return (0, 1, body_b, link_a, -1, (0.5, 0.0, 0.1), (0.5, 0.0, 0.1), (-1.0, 0.0, 0.0),
            distance_m, force_n, 0.0, (0.0, 1.0, 0.0), 0.0, (0.0, 0.0, 1.0))


def test_only_points_that_touch_are_contacts():
    """Penetrating or touching (distance <= 0) is a contact; 7 mm apart is not."""
    points = [point(2, 0.0074, 0.0), point(3, 0.0, 0.0), point(3, -0.001, 12.5, link_a=4),
              point(4, 1e-9, 0.0)]
    records = contact_records(points)
    assert [(r.body_b, r.link_a, r.normal_force_n) for r in records] == [
        (3, 0, 0.0), (3, 4, 12.5)]


def test_the_bodies_ignored_are_left_out():
    """The ground: a robot's wheels touch it at every step."""
    records = contact_records([point(0, -0.001, 40.0), point(5, -0.002, 3.0)], ignoring=[0])
    assert [r.body_b for r in records] == [5]
