DEFAULT TOLERANCE absolute 1.0E-9
COORDINATES absolute 1.0E-12
TIME STEPS absolute 1.0E-14
NODAL VARIABLES absolute 1.0E-12
	DisplacementX   absolute 1.0E-9
	DisplacementY   absolute 1.0E-9
	DisplacementZ   absolute 1.0E-9
	VelocityX       absolute 1.0E-9
	VelocityY       absolute 1.0E-9
	VelocityZ       absolute 1.0E-9
	ForceX          absolute 1.0E-9
	ForceY          absolute 1.0E-9
	ForceZ          absolute 1.0E-9
