"""Transition: CD's targets, the CF fade, feet held across seams, other skeletons (retargeting, casting)."""
