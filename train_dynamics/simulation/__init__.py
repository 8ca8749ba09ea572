"""
Running the model: simulation time in integration steps, the inputs of a run, the run loop.

:mod:`.runner` holds the time grid shared by ``sim_node`` and the offline command (outputs
at the steps nearest to j / rate, an input acting from the first step at or after its time),
the inputs of an offline run (:class:`~.runner.InputSchedule`) and the offline run loop
(:func:`~.runner.run_simulation`). Import rule: the standard library, ``topics`` and
``physics``; never rclpy, ROS message packages, rosbags or matplotlib, nor the
``recording``, ``ros`` or ``cli`` layers.
"""
