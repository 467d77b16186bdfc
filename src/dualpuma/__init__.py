"""dualpuma: two PUMA 560 arms carrying one bar (kinematics, clearance, planning, viewer)."""
