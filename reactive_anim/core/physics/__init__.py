"""Physics (BC and CD): the MuJoCo ragdoll, forward dynamics, PD tracking and the balance assist."""
