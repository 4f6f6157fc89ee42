"""ROS nodes: thin wrappers over the core (each module has main())."""
