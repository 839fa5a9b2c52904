"""engine — integrate the physics in time: input samples in, outputs out (ROS-free).

Holds the input sample (``inputs.RateSample``), the output record (``outputs.Outputs``), the
integrators behind one contract with error control (the ``integrators`` package), the compiled batch
stepping (``batch``), the ``Simulator`` (state, ``push``/``push_many``, outputs), the
catalogue of hard cases (``hardcases``) and one BLAS thread per process (``blas``). May import
``physics`` and ``errors``.
"""
